"""The options of the conversion program (:mod:`radartracker.io.convert`), apart from it so that
``radartracker convert --help`` shows their defaults without importing numpy and the readers."""

from __future__ import annotations

import attrs


@attrs.frozen
class ConvertOptions:
    """The seed's parameters (names as in seed 000 §2.6) and the bucket size of the external sort."""

    AZN_TRACKS_MAX: int = attrs.field(default=100, validator=attrs.validators.ge(1))
    AZN_TRACKS_MIN_MEASUR: int = attrs.field(default=20, validator=attrs.validators.ge(1))
    TRACKS_MIN_MEASUR: int = attrs.field(default=10, validator=attrs.validators.ge(1))
    RADAR_SENSOR_ONLY: str | None = None  # None: keep every sensor type
    bucket_bytes: int = attrs.field(default=32 << 20, validator=attrs.validators.ge(1 << 10))
