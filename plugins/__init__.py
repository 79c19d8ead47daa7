"""Built-in plugins of radartracker, installed as ``radartracker_plugins``.

Each sub-package is an estimator or reconstructor that uses only the public API of
``radartracker`` and registers itself through an entry point, exactly as a third party would.
"""
