"""Errors raised while reading, writing or checking circuits."""


class NetlistError(ValueError):
    """A netlist could not be read or a circuit is malformed.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    file : str, optional
        The netlist file (``"<string>"`` for text given directly).
    line : int, optional
        1-based line number in ``file`` (the first physical line of a continued line).
    text : str, optional
        The offending source text.
    """

    def __init__(
        self,
        message: str,
        file: str | None = None,
        line: int | None = None,
        text: str | None = None,
    ):
        self.message = message
        self.file = file
        self.line = line
        self.text = text
        where = file or "<netlist>"
        if line is not None:
            where = f"{where}:{line}"
        full = f"{where}: {message}"
        if text:
            full += f"\n    {text.strip()}"
        super().__init__(full)
