"""One error hierarchy for everything a user can cause.

Every error that bad input, a bad option or an impossible geometry can cause derives from
:class:`RadarTrackerError`. The CLI turns those (and ``OSError``) into one line and exit 2; any
other exception is a bug and keeps its traceback. The concrete classes also derive from
``ValueError`` so that code written against earlier releases keeps catching them.
"""

from __future__ import annotations


class RadarTrackerError(Exception):
    """Base of every error radartracker raises for a cause outside its own code."""


class InputError(RadarTrackerError, ValueError):
    """Input that cannot be used: a file, a record or a value handed to the API."""


class TableName(str):
    """The name of a table whose records are rows, not lines of text (a Parquet file, a DataFrame): a
    :class:`FormatError` naming it counts its rows from 1 and says ``row 7`` where a text file's says ``line 7``."""


class FormatError(InputError):
    """A row or record of an input file that cannot be used: says file, line, field and why
    (``line`` None where lines mean nothing, as in a JSON document: the field path says where; the row of a
    :class:`TableName`)."""

    def __init__(self, file: str, line: int | None, field: str | None, message: str, reason: str = "malformed"):
        unit = "row" if isinstance(file, TableName) else "line"
        where = file + (f" {unit} {line}" if line is not None else "") + (f", field '{field}'" if field else "")
        super().__init__(f"{where}: {message}")
        self.file, self.line, self.field, self.reason, self.message = file, line, field, reason, message


class ConfigurationError(RadarTrackerError, ValueError):
    """An option, setting or plugin choice that cannot work (unknown name, out of range, refused)."""


class GeometryError(RadarTrackerError, ValueError):
    """A geometry that cannot give an answer (target at a radar, degenerate bearings, bad reference)."""


class NumericalError(RadarTrackerError, ValueError):
    """A computation that lost its footing (a covariance not positive definite, a step refused)."""


class PluginError(RadarTrackerError):
    """A plugin failed; the message names the plugin, the aircraft or radar and the time."""


class SnapshotError(InputError):
    """A snapshot that cannot be restored (truncated, corrupted, foreign, newer): names the file."""

    def __init__(self, file: str, message: str):
        super().__init__(f"{file}: {message}")
        self.file = file
