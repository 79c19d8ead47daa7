"""Track events and the one way they leave a TrackManager: its :class:`EventSink`."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    from radartracker.tracking.track import Track

EVENT_KINDS = ("created", "confirmed", "updated", "coasting", "deleted", "merged")
ENDS = ("deleted", "merged")  # the kinds that end a track number (merged: into an older track)
# new_tuple(SomeNamedTuple, fields): a named tuple made without its Python-level __new__, for the
# events, updates and measurements a manager makes once or more per input
new_tuple = tuple.__new__


class TrackEvent(NamedTuple):
    """Something that happened to a track: ``kind`` is one of ``EVENT_KINDS``, ``status`` the track's
    status after it, ``state`` the track's [x, y, vx, vy] at ``time`` (extrapolated in a straight line
    for coasting and deleted events). Immutable, equal only to a TrackEvent with equal fields."""

    time: float
    track: int
    kind: str
    status: str
    state: tuple[float, float, float, float]

    def __eq__(self, other: object) -> bool:
        return type(other) is TrackEvent and tuple.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    __hash__ = tuple.__hash__


Listener = Callable[[TrackEvent, "Track"], None]


class EventSink:
    """Where a manager's events go, in the order they happen.

    Every event is handed with its track to each listener (:meth:`subscribe`: a recorder reads the
    track's covariance and identity there, an application its own callback), and kept until the
    manager's public call that caused it returns them (:meth:`take`).
    """

    def __init__(self) -> None:
        self._listeners: list[Listener] = []
        self._events: list[TrackEvent] = []

    def subscribe(self, listener: Listener) -> None:
        """Call ``listener(event, track)`` for every later event."""
        self._listeners.append(listener)

    def unsubscribe(self, listener: Listener) -> None:
        self._listeners.remove(listener)

    def emit(self, event: TrackEvent, track: Track) -> None:
        self._events.append(event)
        for listener in self._listeners:
            listener(event, track)

    def take(self) -> list[TrackEvent]:
        """The events since the last call, oldest first."""
        events, self._events = self._events, []
        return events
