"""Shared fixtures: small simulated scenarios (deterministic, a few seconds at most)."""

import pytest

from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="session")
def demo_data():
    return build_scenario("demo", seed=3, duration=600.0).run()


@pytest.fixture(scope="session")
def seed_data():
    return build_scenario("seed", seed=5, duration=600.0).run()
