"""Conformance checks for plugins, in the spirit of scikit-learn's ``check_estimator``.

``check_estimator(cls, **options)`` and ``check_motion_model(cls)`` run the contract and oracle tests
the built-in plugins pass against any plugin class, and raise :class:`CheckFailed` (an
``AssertionError``) naming the plugin, the check and what differed. Each returns the names of the
checks it ran. Use them in a plugin's own test suite::

    from radartracker.testing import check_estimator
    def test_conforms():
        check_estimator(MyEstimator, forgetting=0.99)

Estimator checks (``ESTIMATOR_CHECKS``):

* ``contract`` — constructible with an :class:`EstimatorConfig` (and its options), lists its radars
  and aircraft, refuses a second ``add_aircraft`` of a key (ValueError) and updates of unknown aircraft
  or radars (KeyError/ValueError), returns :class:`BiasState` / :class:`AircraftEstimate` of the
  documented shapes;
* ``filterpy`` — one aircraft measured only by unbiased positions (C_s = 0): every update equals
  FilterPy's ``KalmanFilter`` (F, Q from ``config.motion.transition(dt)``) to 1e-9, innovation ν, Λ
  and NIS included, and the uncorrelated bias does not move;
* ``consistency`` — Monte Carlo over the same unbiased case, where the model is right (truth drawn
  from the prior and the motion model): the summed NEES (4 dof) and NIS (2 dof) fall inside their
  two-sided 99.9 % χ² intervals;
* ``reads`` — reads (``aircraft``, ``bias``, ``predict``, the key lists) leave the state unchanged
  (an untouched deep copy continues identically) and return copies;
* ``lifecycle`` — aircraft are added and removed mid-stream, a removed key can be added again and
  starts from its new prior, the others carry on;
* ``update_many`` — the batch call equals one ``update`` after another (1e-9);
* ``snapshot`` — a ``copy.deepcopy`` and, where the estimator has ``state_dict``, a new instance
  given ``load_state_dict(state_dict())`` continue bit for bit;
* ``kernels`` — no function of the plugin's package compiled by :func:`radartracker.api.kernel`
  (numba without its runtime) returns an array, in what the checks before it compiled (a motion model
  has the same check);
* ``joint_consistency`` (in ``EXACT_CHECKS``, for an exact joint filter that keeps every
  cross-covariance) — Monte Carlo with three aircraft, two biased radars and unbiased positions, truth
  and biases drawn from the priors: summed NIS, aircraft NEES and final bias NEES inside their
  two-sided 99.9 % χ² intervals. The decoupled and Blom filters ignore cross-covariances and fail it,
  as docs/estimators.md measures.

Motion-model checks (``MOTION_CHECKS``): ``contract`` (typed ``config_class``, refuses another
config type, ``predict`` before ``start`` fails), ``errors`` (non-finite or malformed z, R, time and a
gap beyond ``max_gap_s`` raise ValueError and leave the filter unchanged), ``reads`` (``predict`` and
``estimate`` change nothing; ``update``'s NIS is that of ``predict``'s output), ``screen`` (``screen``'s
bias correction and d² are screening's equations on ``predict``'s output; outside the gate nothing
changes, inside it the filter is updated as ``update`` does), ``filterpy`` (for a
single-Gaussian filter, ``kalman_update=True``: the update is FilterPy's Kalman correction of
``predict``'s (χ̄, P̄)), ``hygiene`` (symmetric positive definite finite covariances through a 2 g
manoeuvre, repeated times and a long gap), ``consistency`` (on straight constant-velocity flight with
q = 1 m²/s³ and the truth's initial velocity drawn from the prior, the mean NEES and NIS are not
above their 99.9 % χ² bounds: a model may be cautious, not overconfident), ``snapshot`` and ``kernels``.

Associator checks (``ASSOCIATOR_CHECKS``, :mod:`radartracker.testing.associators`): ``contract``,
``obvious`` (plots at well separated tracks go to them, far and impossible plots to none) and ``manager``
(a TrackManager with it confirms tracks on a built-in scenario and accounts for every input).

All data are generated here from fixed seeds, so a check gives the same verdict every time; a whole
plugin takes a few seconds.
"""

from radartracker.testing.associators import ASSOCIATOR_CHECKS, check_associator
from radartracker.testing.common import CheckFailed
from radartracker.testing.estimators import ESTIMATOR_CHECKS, EXACT_CHECKS, check_estimator
from radartracker.testing.motion import MOTION_CHECKS, check_motion_model

__all__ = ["ASSOCIATOR_CHECKS", "CheckFailed", "check_associator", "ESTIMATOR_CHECKS", "EXACT_CHECKS", "MOTION_CHECKS", "check_estimator", "check_motion_model"]
