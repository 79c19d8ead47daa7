"""StateTable gives the rows a direct read of every live track's estimate gives (oracle: that read)."""

import numpy as np

from radartracker.tracking.states import StateTable


class _Track:
    def __init__(self, tid: int, rng: np.random.Generator) -> None:
        self.id = tid
        self.estimate = None
        self.move(rng)

    def move(self, rng: np.random.Generator) -> None:
        self.estimate = (float(rng.uniform(0, 100)), rng.normal(0, 1e4, 5), None)


def _direct(live):
    return (np.array([tr.estimate[0] for tr in live]).reshape(len(live)),
            np.array([tr.estimate[1][:4] for tr in live]).reshape(len(live), 4))


def test_rows_follow_starts_changes_and_ends_through_compaction():
    rng = np.random.default_rng(5)
    table, live, ids = StateTable(), [], iter(range(1, 10**6))
    for step in range(300):
        for _ in range(rng.integers(0, 30)):  # tracks start
            tr = _Track(next(ids), rng)
            live.append(tr)
            table.add(tr)
        for tr in rng.choice(live, min(len(live), 20), replace=False) if live else []:  # estimates change
            tr.move(rng)
            table.changed(tr)
        for k in sorted(rng.choice(len(live), min(len(live), rng.integers(0, 25)), replace=False), reverse=True):
            table.remove(live.pop(k).id)  # tracks end, anywhere in the order
        t = float(rng.uniform(0, 100))  # after some estimates, before others
        pos = table.positions(live, lambda tr: tr.estimate, t)
        t0, x = table.read(live, lambda tr: tr.estimate)
        want_t0, want_x = _direct(live)
        np.testing.assert_array_equal(t0, want_t0)
        np.testing.assert_array_equal(x, want_x)
        # the straight-line extrapolation, as numpy's expression of it rounds it (oracle)
        np.testing.assert_array_equal(pos, want_x[:, :2] + want_x[:, 2:] * np.maximum(t - want_t0, 0.0)[:, None])
    assert table._used < 4 * len(live) + 2048  # removed rows are dropped, not kept for ever


def test_a_table_out_of_step_with_the_tracks_is_rebuilt_from_them():
    rng = np.random.default_rng(1)
    live = [_Track(k, rng) for k in range(1, 6)]
    table = StateTable(live[:3])  # two tracks never added
    t0, x = table.read(live, lambda tr: tr.estimate)
    np.testing.assert_array_equal(x, _direct(live)[1])
