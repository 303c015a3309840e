"""The pattern model: slopers, strokes, drafting, edit Jacobians, validation, I/O.

Pure library (no bus). Entry points::

    draft(design) -> DraftedPattern
    validate(design) -> DraftedPattern           # raises PatternError naming the element
    edit_jacobian(design, element_id) -> {panel: PanelJacobian}
    apply_edit(design, element_id, dd) -> Design
    place(panel, points2d) -> points3d
"""

from couture.pattern.draft import SPACING, draft, draft_with_context
from couture.pattern.edit import apply_edit, edit_elements, edit_jacobian
from couture.pattern.errors import PatternError
from couture.pattern.options import Option
from couture.pattern.placement import place
from couture.pattern.slopers import SLOPERS
from couture.pattern.validate import validate

__all__ = [
    "SPACING",
    "SLOPERS",
    "Option",
    "PatternError",
    "apply_edit",
    "draft",
    "draft_with_context",
    "edit_elements",
    "edit_jacobian",
    "place",
    "validate",
]
