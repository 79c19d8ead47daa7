"""Reconstruction settings, with the seed's constants as defaults (seed 000 §2.5, DESIGN §7)."""

from __future__ import annotations

import attrs

from radartracker_plugins.reconstruction.weight import LOSSES


def _pos(inst, attr, value) -> None:
    if not value > 0:
        raise ValueError(f"{attr.name}: must be > 0, got {value!r}")


@attrs.frozen
class ReconstructionConfig:
    """Every knob of the reconstruction.

    Seed constants: initial steps ``du1``, ``dw1`` (m/s²), ``dt1`` (s); final steps ``du_fin``,
    ``dw_fin``, ``dt_fin``; bounds ``max_u``, ``max_w`` (m/s²; 4 and 2 in seed 000, 9.5 in its
    revision 002; here 9.5 and 3, the best on approach, departure, cruise and calibration flights at
    once, measured in docs/reconstruction.md *Control bounds*: the seed's 4 pinned on 5 of 7 real approaches);
    ``dt_min`` the shortest segment (s); ``dh`` the step factor.

    Beyond the seed: the initial state (x, y, φ, v) is optimised too, with steps ``dxy1``/``dxy_fin``
    (m), ``dphi1``/``dphi_fin`` (rad), ``dv1``/``dv_fin`` (m/s); ``v_min`` keeps the speed positive
    (the model is singular at v = 0); ``penalty`` scales the constraint-violation penalty (per step
    unit); ``refine`` adds a joint least-squares refinement after the Hooke–Jeeves pass (at most
    ``refine_iterations`` evaluations; see :func:`.fit.refine`), preceded by a multiple-shooting
    one when ``shooting`` (Gaussian weight only, at most ``shooting_iterations`` evaluations;
    see :mod:`.shooting`); ``loss``/``loss_c`` choose the weight (see :mod:`.weight`);
    ``grid_dt`` is the geometric-track spacing (s); ``hypotheses`` the most segment counts
    optimised (see :mod:`.hypotheses`); ``max_segments`` caps the segment count; ``complexity`` the
    per-parameter penalty factor on ln n (1 = BIC); ``jump_sd`` (m/s², 0 = off, the default) the prior sd of each
    control jump u_k − u_{k−1}, w_k − w_{k−1} — piecewise-constant-acceleration process noise, so
    the fit is a MAP fit (see :func:`.fit.jump_prior`).
    """

    du1: float = attrs.field(default=0.5, validator=_pos)
    dw1: float = attrs.field(default=0.25, validator=_pos)
    dt1: float = attrs.field(default=32.0, validator=_pos)
    du_fin: float = attrs.field(default=0.01, validator=_pos)
    dw_fin: float = attrs.field(default=0.01, validator=_pos)
    dt_fin: float = attrs.field(default=0.02, validator=_pos)
    max_u: float = attrs.field(default=9.5, validator=_pos)  # chosen by measurement: docs/reconstruction.md
    max_w: float = attrs.field(default=3.0, validator=_pos)
    dt_min: float = attrs.field(default=10.0, validator=_pos)
    dh: float = attrs.field(default=0.5, validator=attrs.validators.and_(_pos, attrs.validators.lt(1.0)))
    dxy1: float = attrs.field(default=50.0, validator=_pos)
    dxy_fin: float = attrs.field(default=0.5, validator=_pos)
    dphi1: float = attrs.field(default=0.02, validator=_pos)
    dphi_fin: float = attrs.field(default=1e-4, validator=_pos)
    dv1: float = attrs.field(default=2.0, validator=_pos)
    dv_fin: float = attrs.field(default=0.01, validator=_pos)
    v_min: float = attrs.field(default=10.0, validator=_pos)
    penalty: float = attrs.field(default=1e4, validator=_pos)
    refine: bool = True
    shooting: bool = True
    shooting_iterations: int = attrs.field(default=100, validator=_pos)
    refine_iterations: int = attrs.field(default=200, validator=_pos)
    loss: str = attrs.field(default="gauss", validator=attrs.validators.in_(LOSSES))
    loss_c: float = attrs.field(default=3.0, validator=_pos)
    grid_dt: float = attrs.field(default=1.0, validator=_pos)
    hypotheses: int = attrs.field(default=10, validator=_pos)
    max_segments: int = attrs.field(default=80, validator=_pos)
    complexity: float = attrs.field(default=1.0, validator=attrs.validators.ge(0.0))
    jump_sd: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0))  # off: measured in docs/reconstruction.md
