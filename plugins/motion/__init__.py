"""Track motion models (``radartracker.motion_models`` plugins): one track's kinematic filter.

* ``cv`` — constant velocity with white-acceleration density q (:class:`CVFilter`);
* ``imm`` — interacting multiple model, constant velocity + coordinated turn (:class:`IMMFilter`);
* ``adaptive`` — seed 004's EUROCAT-X filter, P̄ = α A P̂ Aᵀ + β Q with α + β = 1 (:class:`AdaptiveFilter`);
* ``fading`` — the classic fading-memory filter, P̄ = λ A P̂ Aᵀ + Q, λ ≥ 1 (:class:`FadingFilter`).

Every filter keeps χ = [x, y, vx, vy] in the system plane and is fed positions z with covariance R;
see ``docs/tracking.md`` for the equations and the measured comparison.
"""

from radartracker_plugins.motion.adaptive import AdaptiveFilter, FadingFilter
from radartracker_plugins.motion.cv import CVFilter
from radartracker_plugins.motion.imm import IMMFilter

__all__ = ["AdaptiveFilter", "CVFilter", "FadingFilter", "IMMFilter"]
