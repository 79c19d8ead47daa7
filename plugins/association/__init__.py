"""Built-in associators (``radartracker.associators`` entry points): ``gnn`` and ``labels``."""

from .gnn import GnnAssociator
from .labels import LabelAssociator

__all__ = ["GnnAssociator", "LabelAssociator"]
