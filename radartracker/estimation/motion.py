"""Aircraft motion model in the system plane: constant velocity (seed 000 eq. 1.4).

χ = [x, y, vx, vy];  χ(t+dt) = A(dt) χ(t) + v,  A = [[I, dt·I], [0, I]],
with v ~ N(0, Q(dt)) the discretised white-acceleration noise of spectral density ``q``
(m²/s³): Q = q·[[dt³/3·I, dt²/2·I], [dt²/2·I, dt·I]]. ``q = 0`` is the seed's noiseless model.
"""

from __future__ import annotations

import attrs
import numpy as np

_I2 = np.eye(2)


@attrs.frozen
class MotionModel:
    """Constant-velocity motion with white-acceleration process noise density ``q`` (m²/s³)."""

    q: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0))

    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(A(dt), Q(dt)) for a step of ``dt`` seconds."""
        A = np.eye(4)
        A[0, 2] = A[1, 3] = dt
        if self.q == 0.0 or dt == 0.0:
            return A, np.zeros((4, 4))
        adt = abs(dt)
        Q = self.q * np.block(
            [[adt**3 / 3 * _I2, adt**2 / 2 * _I2], [adt**2 / 2 * _I2, adt * _I2]]
        )
        return A, Q
