"""The live bench: the translated circuit running in chunks, knobs turned while it runs (the
matrix is restamped, the state carries on), the direct ODE with the same knob history beside
it, a JSON API and a Bokeh page (docs/bench.md).

Nothing here prints; the CLI (``circuitsim bench``) starts the server.
"""
