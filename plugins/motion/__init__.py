"""Track motion models (``radartracker.motion_models`` plugins): one track's kinematic filter.

* ``cv`` — constant velocity with white-acceleration density q (:class:`CVFilter`);
* ``imm`` — interacting multiple model, constant velocity + coordinated turn (:class:`IMMFilter`);
* ``adaptive`` — seed 004's EUROCAT-X filter, P̄ = α A P̂ Aᵀ + β Q with α + β = 1 (:class:`AdaptiveFilter`);
* ``fading`` — the classic fading-memory filter, P̄ = λ A P̂ Aᵀ + Q, λ ≥ 1 (:class:`FadingFilter`).

Every filter keeps χ = [x, y, vx, vy] in the system plane and is fed positions z with covariance R;
see ``docs/tracking.md`` for the equations and the measured comparison. Each has its own typed
settings class (``CVConfig``, ``IMMConfig``, ``AdaptiveConfig``, ``FadingConfig``), its ``config_class``.
"""

from radartracker_plugins.motion.adaptive import AdaptiveConfig, AdaptiveFilter, FadingConfig, FadingFilter
from radartracker_plugins.motion.cv import CVConfig, CVFilter
from radartracker_plugins.motion.imm import CTMode, CVMode, IMMConfig, IMMFilter

__all__ = ["AdaptiveConfig", "AdaptiveFilter", "CTMode", "CVConfig", "CVFilter", "CVMode", "FadingConfig",
           "FadingFilter", "IMMConfig", "IMMFilter"]
