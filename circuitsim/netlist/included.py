"""Expressions read from included files, marked as such: a message about one names the
file instead of quoting it (a ``.include`` may pull in a file that is not the user's to show,
and the reader never quotes such a file's lines either)."""

from __future__ import annotations

import dataclasses

from circuitsim.netlist.circuit import Expression


def expressions(state: object) -> list[Expression]:
    """Every Expression reachable from ``state`` (lists, dicts, tuples, dataclasses)."""
    found: list[Expression] = []

    def visit(value: Expression) -> Expression:
        found.append(value)
        return value

    _walk(state, visit)
    return found


def mark_included(state: object, before: list[Expression], file: str) -> None:
    """Mark, in place, every Expression reachable from ``state`` that is not one of
    ``before`` (kept alive by the caller, so no id is reused) and not marked yet, as read
    from ``file``."""
    known = {id(e) for e in before}

    def mark(value: Expression) -> Expression:
        if id(value) in known or value.included is not None:
            return value
        return dataclasses.replace(value, included=file)

    _walk(state, mark)


def _walk(value: object, visit) -> object:
    """``value`` with ``visit`` applied to each Expression inside it: mutable containers and
    dataclasses changed in place, frozen dataclasses and tuples rebuilt when something in
    them changed."""
    if isinstance(value, Expression):
        return visit(value)
    if isinstance(value, list):
        for k, item in enumerate(value):
            value[k] = _walk(item, visit)
        return value
    if isinstance(value, dict):
        for key, item in value.items():
            value[key] = _walk(item, visit)
        return value
    if isinstance(value, tuple):
        items = tuple(_walk(item, visit) for item in value)
        return items if any(a is not b for a, b in zip(items, value, strict=True)) else value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        changes = {}
        for f in dataclasses.fields(value):
            old = getattr(value, f.name)
            new = _walk(old, visit)
            if new is not old:
                changes[f.name] = new
        if changes:
            if type(value).__dataclass_params__.frozen:
                return dataclasses.replace(value, **changes)
            for name, new in changes.items():
                setattr(value, name, new)
        return value
    return value
