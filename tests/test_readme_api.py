"""Every Python name the README's API paragraph lists can be reached as written."""

import importlib
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _resolve(dotted: str, base: str | None):
    """``dotted`` as a module path or attribute chain, from the top or from module ``base``."""
    parts = dotted.split(".")
    start = [] if parts[0] == "circuitsim" else [base]
    for cut in range(len(parts), 0, -1):  # the longest importable module prefix
        name = ".".join([*start, *parts[:cut]])
        try:
            obj = importlib.import_module(name)
        except ImportError:
            continue
        for attribute in parts[cut:]:
            obj = getattr(obj, attribute)
        return obj, name if cut == len(parts) and parts[0] == "circuitsim" else base
    obj = importlib.import_module(base)
    for attribute in parts:
        obj = getattr(obj, attribute)
    return obj, base


def test_readme_api_names_resolve():
    text = README.read_text()
    paragraph = text[text.index("The Python API mirrors the commands:") :].split("\n\n")[0]
    names = re.findall(r"`([\w.]+)`", paragraph)
    assert len(names) > 15
    base = None
    for name in names:
        obj, base = _resolve(name, base)
        assert callable(obj) or hasattr(obj, "__path__") or hasattr(obj, "__file__"), name
