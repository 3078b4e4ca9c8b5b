"""The ``circuitsim`` command line: parses options, calls the library, prints.

Each verb is a pair of functions: ``_add_<verb>(subparsers)`` declares its options and
``_run_<verb>(args) -> int`` does the work and returns the exit code. ``COMMANDS`` lists the
``_add_`` functions in the order ``--help`` shows them. Library errors are turned into one
readable line on stderr and exit code 1 (2 for unreadable input where a verb says so).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from circuitsim import __version__


def _library_errors() -> tuple[type[BaseException], ...]:
    """The typed errors of every room, caught at the top and printed as one line."""
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.mechanics.errors import ModelError
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver.errors import SolverError
    from circuitsim.synthesis.errors import SynthesisError

    return (ModelError, NetlistError, SolverError, SynthesisError, NgspiceError)


def _progress(message: str) -> None:
    """Progress callback handed to long-running library calls: one line on stderr."""
    print(message, file=sys.stderr, flush=True)


# --- verbs -------------------------------------------------------------------------------
# Each helper section below adds one verb; keep each small and put the work in the library.


COMMANDS: list[Callable[[argparse._SubParsersAction], None]] = []


# --- end of verbs ---


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered verb."""
    parser = argparse.ArgumentParser(
        prog="circuitsim",
        description=(
            "Mechanical ODE models and their op-amp analog-computer circuits: direct solution, "
            "stability, netlist generation, circuit simulation and comparison."
        ),
    )
    parser.add_argument("--version", action="version", version=f"circuitsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except _library_errors() as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return getattr(args, "error_exit_code", 1)
    except OSError as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
