"""Project exceptions: bad input is reported with the place it came from."""

from __future__ import annotations


class InputError(ValueError):
    """Input data that cannot be used, with where the problem is.

    Parameters
    ----------
    message
        What is wrong and what was expected.
    source
        File name, stream name or request field the problem is in.
    line
        1-based line number in a text file, when known.
    field
        Column, key or stream the problem is in, when known.
    """

    code = "invalid_input"

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.message = message
        self.source = source
        self.line = line
        self.field = field
        super().__init__(self._render())

    def _render(self) -> str:
        where = []
        if self.source:
            where.append(str(self.source))
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.field:
            where.append(f"field '{self.field}'")
        return f"{', '.join(where)}: {self.message}" if where else self.message

    def details(self) -> dict[str, object]:
        """Machine-readable location of the problem (for API error bodies)."""
        return {k: v for k, v in {"source": self.source, "line": self.line, "field": self.field}.items()
                if v is not None}


class UnknownFormatError(InputError):
    """The input matches none of the supported log formats."""

    code = "unknown_format"
