"""The bench's page: a Bokeh document with the knobs, the oscilloscope and the session's
controls, one per browser tab, all driving the one running session.

The oscilloscope shows each state in its SI unit: the circuit's trace (solid) and the
direct ODE with the same knob history (dashed), scrolling over the last ``WINDOW`` model
seconds, fed every ``REFRESH_MS`` from the session's samples (Bokeh streams only the new
ones to the browser). Model names (``trace_y``, ``knob_speed`` ...) let scripts and the
browser test find them in ``Bokeh.documents[0]``.
"""

from __future__ import annotations

import math

from circuitsim.bench.errors import BenchError
from circuitsim.bench.knobs import Knob
from circuitsim.bench.runner import BenchRunner

#: Model seconds the oscilloscope shows.
WINDOW = 10.0

#: Milliseconds between the page's updates.
REFRESH_MS = 200

#: Most samples sent to the browser per state and update (a higher rate is thinned).
MAX_POINTS = 1000


def knob_range(knob: Knob, value: float, reference: float | None) -> tuple[float, float, float]:
    """Slider (start, end, step) of a number knob around its starting ``value``: the
    amplitude from 0 to twice ``reference``, the frequency from 0.1 Hz to 20 Hz or more,
    any other from half to 1.5 times its value."""
    if knob.name == "amplitude":
        start, end = 0.0, 2 * (reference or abs(value) or 1.0)
    elif knob.name == "freq":
        start, end = 0.1, max(20.0, 2 * value)
    else:
        start, end = sorted((0.5 * value, 1.5 * value)) if value else (-1.0, 1.0)
    return start, end, (end - start) / 1000


def _ohms(value: float) -> str:
    """``11.81 kΩ``."""
    for scale, prefix in ((1e6, "M"), (1e3, "k")):
        if abs(value) >= scale:
            return f"{value / scale:.4g} {prefix}Ω"
    return f"{value:.4g} Ω"


def _pot_text(pot) -> str:
    """``R33 = R33A 80.6 kΩ + R33P (68 kΩ) at 0.472``."""
    return (
        f"{pot.resistor} = {pot.fixed_part} {_ohms(pot.fixed)} + {pot.pot_part} "
        f"({_ohms(pot.pot)}) at {pot.setting.fraction:.3f}"
    )


class BenchPage:
    """Builds and updates one Bokeh document over ``runner``'s session."""

    def __init__(self, runner: BenchRunner, doc):
        from bokeh.layouts import column, row
        from bokeh.models import Div

        self.runner = runner
        self.session = runner.session
        self.doc = doc
        self.last_t = -math.inf
        self.syncing = False
        self.status = Div(text="", name="status", width=420)
        self.nrmsd = Div(text="", name="nrmsd", width=420)
        self.sources, figures = self._oscilloscope()
        controls = column(
            Div(text=f"<h2>circuitsim bench: {self.session.system.name}</h2>"),
            *self._knob_widgets(),
            *self._push_widgets(),
            *self._run_widgets(),
            self.nrmsd,
            self.status,
            width=440,
        )
        doc.add_root(row(controls, column(*figures)))
        doc.title = f"circuitsim bench: {self.session.system.name}"
        doc.add_periodic_callback(self.update, REFRESH_MS)
        self.update()

    # --- the oscilloscope ------------------------------------------------------------------

    def _oscilloscope(self):
        from bokeh.models import ColumnDataSource, DataRange1d
        from bokeh.plotting import figure

        session = self.session
        x_range = DataRange1d(follow="end", follow_interval=WINDOW, range_padding=0)
        sources, figures = {}, []
        for name, unit in zip(session.states, session.units, strict=True):
            source = ColumnDataSource({"t": [], "circuit": [], "ode": []}, name=f"trace_{name}")
            plot = figure(
                height=175,
                width=720,
                x_range=x_range,
                name=f"scope_{name}",
                y_axis_label=f"{name} ({unit})" if unit else name,
                tools="pan,wheel_zoom,box_zoom,reset,save",
            )
            plot.line("t", "circuit", source=source, line_width=2, legend_label="circuit")
            plot.line(
                "t",
                "ode",
                source=source,
                line_width=1.5,
                line_dash="dashed",
                color="orange",
                legend_label="ODE",
            )
            plot.legend.location = "top_left"
            sources[name] = source
            figures.append(plot)
        figures[-1].xaxis.axis_label = "model time (s)"
        return sources, figures

    def update(self) -> None:
        """Stream the new samples, show the NRMSD, follow knob changes made elsewhere."""
        data = self.session.trace(self.last_t, last=WINDOW)
        if data["t"]:
            stride = max(1, math.ceil(len(data["t"]) / MAX_POINTS))
            keep = round(WINDOW / (self.session.sample * stride)) + 1
            for name, source in self.sources.items():
                source.stream(
                    {
                        "t": data["t"][::stride],
                        "circuit": data["states"][name][::stride],
                        "ode": data["ode"][name][::stride],
                    },
                    rollover=keep,
                )
            self.last_t = data["t"][-1]
        errors = self.session.nrmsd()
        shown = ", ".join(f"{k} {v:.3f} %" for k, v in errors.items() if math.isfinite(v))
        running = "running" if self.runner.running else "paused"
        if self.runner.error:
            running = f"stopped: {self.runner.error}"
        self.nrmsd.text = (
            f"t = {self.session.t:.2f} s ({running}, rate {self.runner.rate:g})"
            f"<br>NRMSD circuit vs ODE: {shown or '-'}"
        )
        self._sync_knobs()

    # --- knobs ---------------------------------------------------------------------------

    def _knob_widgets(self) -> list:
        from bokeh.models import Div, Slider, Toggle

        values = self.session.knob_values()
        reference = self.session.setup.reference_amplitude()
        self.widgets, self.part_labels, out = {}, {}, []
        for knob in self.session.knobs:
            value = values[knob.name]
            if knob.kind == "switch":
                parts = "/".join(knob.parts) or knob.name
                widget = Toggle(
                    label=f"{parts} {knob.name}",
                    active=bool(value),
                    name=f"knob_{knob.name}",
                    width=420,
                )
                widget.on_change("active", self._on_knob(knob.name))
                out.append(widget)
            else:
                start, end, step = knob_range(knob, value, reference)
                pot = self.session.setup.pot
                if pot is not None and knob.parameter == pot.parameter:  # the dial's range
                    start, end, step = pot.low, pot.high, (pot.high - pot.low) / 1000
                title = (
                    f"{knob.name} = {knob.parameter} ({knob.unit})"
                    if knob.parameter != (knob.name)
                    else f"{knob.name} ({knob.unit})"
                )
                widget = Slider(
                    start=start,
                    end=end,
                    value=value,
                    step=step,
                    title=title,
                    name=f"knob_{knob.name}",
                    width=420,
                    format="0[.]0000",
                )
                widget.on_change("value_throttled", self._on_knob(knob.name))
                label = Div(text="", name=f"parts_{knob.name}", width=420)
                self.part_labels[knob.name] = label
                out += [widget, label]
            self.widgets[knob.name] = widget
        self._show_parts()
        return out

    def _on_knob(self, name: str):
        def changed(attr, old, new) -> None:
            if self.syncing:
                return
            try:
                t = self.session.set_knobs({name: new})
                self.status.text = f"{name} = {new:g} from t = {t:.2f} s"
            except BenchError as exc:
                self.status.text = f"<b>refused</b>: {exc}"
            self._sync_knobs()

        return changed

    def _show_parts(self) -> None:
        resistors = self.session.resistors
        pots = {pot.pot_part: pot for pot in self.session.pots}
        for knob in self.session.knobs:
            label = self.part_labels.get(knob.name)
            if label is not None:
                shown = [
                    _pot_text(pots[p]) if p in pots else f"{p} = {_ohms(resistors[p])}"
                    for p in knob.parts
                    if p in resistors
                ]
                label.text = ("<small>" + ", ".join(shown) + "</small>") if shown else ""

    def _sync_knobs(self) -> None:
        """Widgets follow the session's values (changed by the API or another tab)."""
        values = self.session.knob_values()
        self.syncing = True
        try:
            for name, widget in self.widgets.items():
                if hasattr(widget, "active"):
                    if widget.active != values[name]:
                        widget.active = values[name]
                elif widget.value != values[name]:
                    widget.update(
                        start=min(widget.start, values[name]),
                        end=max(widget.end, values[name]),
                        value=values[name],
                    )
            paused = not self.runner.running
            if self.pause.active != paused and self.runner.error is None:
                self.pause.active = paused
            rate = None if math.isinf(self.runner.rate) else self.runner.rate
            if self.rate.value != rate:
                self.rate.value = rate
        finally:
            self.syncing = False
        self._show_parts()

    # --- push and run ----------------------------------------------------------------------

    def _push_widgets(self) -> list:
        from bokeh.models import Button, NumericInput, Select

        states = list(self.session.states)
        self.push_state = Select(
            title="push: state", value=states[0], options=states, name="push_state", width=200
        )
        unit = self.session.units[0]
        self.push_value = NumericInput(
            title=f"value (SI units, {states[0]} in {unit})",
            value=0.005,
            mode="float",
            name="push_value",
            width=200,
        )
        button = Button(label="push", name="push", width=100)
        button.on_click(self._push)
        return [self.push_state, self.push_value, button]

    def _push(self) -> None:
        value = self.push_value.value
        try:
            t = self.session.set_state({self.push_state.value: value})
            self.status.text = f"pushed {self.push_state.value} = {value:g} at t = {t:.2f} s"
        except BenchError as exc:
            self.status.text = f"<b>refused</b>: {exc}"

    def _run_widgets(self) -> list:
        from bokeh.models import Div, NumericInput, Toggle

        self.pause = Toggle(label="pause", active=not self.runner.running, name="pause", width=100)
        self.pause.on_change("active", self._pause_changed)
        rate = NumericInput(
            title="rate (model s per wall s)",
            mode="float",
            name="rate",
            value=None if math.isinf(self.runner.rate) else self.runner.rate,
            width=200,
        )
        rate.on_change("value", self._rate_changed)
        export = Div(
            text='export: <a href="/api/export/trace.csv" download>traces (CSV)</a>, '
            '<a href="/api/export/history.json" download>knob history '
            "(JSON)</a>"
        )
        self.rate = rate
        return [self.pause, rate, export]

    def _pause_changed(self, attr, old, new) -> None:
        if not self.syncing:
            self.runner.pause() if new else self.runner.resume()

    def _rate_changed(self, attr, old, new) -> None:
        if self.syncing:
            return
        try:
            self.runner.set_rate(new if new is not None else math.inf)
        except BenchError as exc:
            self.status.text = f"<b>refused</b>: {exc}"


def page_application(runner: BenchRunner):
    """A Bokeh Application that builds a :class:`BenchPage` for each browser tab."""
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler

    def make_document(doc) -> None:
        BenchPage(runner, doc)  # kept alive by its periodic callback

    return Application(FunctionHandler(make_document))
