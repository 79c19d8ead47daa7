"""``radartracker serve``: a live surveillance service (docs/service.md).

ASTERIX CAT048 plots and CAT021 ADS-B reports arrive as UDP datagrams (:mod:`.endpoints`,
:mod:`.receiver`: one reader thread, a bounded queue, drops counted), are decoded into plots and
reports (:mod:`.decoder`), tracked by the :class:`~radartracker.tracking.manager.TrackManager`
(:mod:`.service`, the loop), and leave as CAT062 system tracks every period (:mod:`.publisher`),
bias estimates in JSON, Prometheus metrics (:mod:`.metrics`, :mod:`.http`) and checkpoints
(:mod:`.checkpoints`) from which a restarted service resumes. :mod:`.sender` replays a recording
onto the network (``radartracker send``); :mod:`.score` scores the CAT062 output against a truth.
"""

from radartracker.service.endpoints import Endpoint, parse_endpoint
from radartracker.service.service import Service, ServiceConfig

__all__ = ["Endpoint", "Service", "ServiceConfig", "parse_endpoint"]
