"""The friction state of a converged drape, read back from its positions.

The solver converges a model whose friction term is springs to anchors
(``couture.cloth.model``: a vertex in contact is tied to its anchor by a
tangential spring up to the static Coulomb limit; a slipping vertex feels a
constant kinetic force instead). The sensitivity node receives only the
positions x of that equilibrium, not the solver's anchors, so it rebuilds
them: at a balance every vertex in contact holds, through its friction
term, exactly the tangential force the other terms leave unbalanced, so

- a vertex in contact whose needed friction force is inside the static cone
  (|f_t| < mu_s f_n) *sticks*: an anchor spring with its normal frozen at the
  contact normal of x and its anchor where the spring holds that force
  (``a = x + f_t / k_t``, as ``ClothModel.stick_slipping`` does), so the
  linearisation sees the spring's tangential stiffness;
- a vertex at the limit (|f_t| >= ``slide_at`` mu_s f_n) *slides*: it is
  given the needed force as a constant (kinetic) force and no anchor, so the
  linearisation sees no tangential stiffness there;
- vertices out of contact have no friction.

The rebuilt state balances x exactly as the solver's did (the residual of
the rebuilt model at x is the frictionless residual's normal part). Its
normals are the contact normals at x rather than at the anchors' creation
(the signed distance's gradient is constant along a normal, so they agree
to the anchors' tangential offset over the body's radius, micrometres over
decimetres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from couture.cloth.model import ClothModel


@dataclass(frozen=True)
class FrictionHeld:
    """What :func:`hold_friction` set up."""

    sticking: int = 0
    """vertices tied to anchors (linearised with their spring stiffness)"""
    sliding: int = 0
    """vertices at the Coulomb limit (a constant force, no tangential stiffness)"""
    max_ratio: float = 0.0
    """largest |f_t| / (mu_s f_n) among vertices in contact (1: at the limit)"""


def hold_friction(model: ClothModel, x: np.ndarray, slide_at: float = 0.999) -> FrictionHeld:
    """Set ``model``'s friction state to the one that balances the equilibrium x
    (see the module docstring); a model without a friction term is left alone.
    ``slide_at``: the fraction of the static limit from which a vertex counts
    as sliding."""
    if "friction" not in model.terms:
        return FrictionHeld()
    x = np.ascontiguousarray(x, dtype=np.float64)
    model.release_friction()
    phi, grad = model._contact(x)
    pen = model.contact_offset - np.asarray(phi)
    contact = (pen > 0.0) & model.free
    if not contact.any():
        return FrictionHeld()
    idx = np.nonzero(contact)[0]
    n_ = grad[idx] / np.maximum(np.linalg.norm(grad[idx], axis=1), 1e-300)[:, None]
    others = [t for t in model.terms if t != "friction"]
    need = -model.forces(x, others)[idx]  # the friction force a balance needs
    ft = need - np.einsum("ij,ij->i", need, n_)[:, None] * n_
    fn = model.contact_normal_force(pen[idx])
    limit = model.friction_coefficients(idx)[0] * fn
    mag = np.linalg.norm(ft, axis=1)
    ratio = np.where(limit > 0, mag / np.maximum(limit, 1e-300), np.where(mag > 0, np.inf, 0.0))
    slide = ratio >= slide_at
    stick = idx[~slide]
    model.anchored[stick] = True
    model.sliding[stick] = False
    model.anchor_normal[stick] = n_[~slide]
    model.anchor[stick] = x[stick] + ft[~slide] / model.friction_stiffness
    sl = idx[slide]
    model.slipping[sl] = True
    model.slip_force[sl] = ft[slide]
    return FrictionHeld(int(len(stick)), int(len(sl)), float(ratio.max()) if len(ratio) else 0.0)
