"""The one exception type of the pattern model."""

from __future__ import annotations


class PatternError(ValueError):
    """A pattern cannot be drafted, edited or validated.

    ``element`` names what is wrong in the vocabulary of edit element ids:
    ``'param:<name>'``, a stroke id, ``'<panel>'``, ``'<panel>:<segment>'``,
    ``'seam:<...>'``; or, for a number outside its physical range, the
    field's path in the design (``'fabric.area_density'``,
    ``'resolution.fine_vertices'``, ``'body.name'``). The message always repeats it, with the offending value
    and, for options, the allowed range.
    """

    def __init__(self, element: str, message: str):
        self.element = element
        super().__init__(f"{element}: {message}")
