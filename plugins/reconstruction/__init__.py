"""Multi-hypothesis trajectory reconstruction (seed 000 §2, DESIGN §7): the ``multi-hypothesis`` reconstructor.

A flight's plots are explained by the seed's kinematic model (eq. 2.1) flown with piecewise-constant
controls; the number of segments, the switch times and the controls are found by generating
hypotheses, optimising each by Hooke–Jeeves, and selecting by weight plus a complexity penalty.
See docs/reconstruction.md.
"""

from radartracker.api import lazy_exports

# imported when first used: `radartracker reconstruct` registers its command without numpy or scipy
_EXPORTS = {
    ".reconstructor": ("MultiHypothesisReconstructor",),
    ".config": ("ReconstructionConfig",),
    ".engine": ("Failure",),
    ".hypotheses": ("Hypothesis", "Reconstruction"),
    ".objects": ("ControlSegment", "ControlTrack", "GeoPoint", "GeoTrack", "PlotTrack"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
