"""Which packages the distribution holds, found rather than listed (the metadata is in pyproject.toml):
every package under ``radartracker/``, and the built-in plugins of folder ``plugins/`` with every
package under it, installed as ``radartracker_plugins``."""

from setuptools import find_packages, setup

PLUGINS = "radartracker_plugins"

setup(
    packages=[*find_packages(include=["radartracker", "radartracker.*"]), PLUGINS,
              *(f"{PLUGINS}.{name}" for name in find_packages("plugins"))],
    package_dir={PLUGINS: "plugins"},
)
