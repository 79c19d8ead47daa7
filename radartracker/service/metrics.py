"""Prometheus metrics of the service (``/metrics``, text exposition format, ``prometheus_client``).

=========================================  =======  ==================================================
metric                                     type     labels / meaning
=========================================  =======  ==================================================
radartracker_datagrams_total               counter  ``outcome``: received, dropped_queue_full,
                                                    dropped_at_stop, refused_sender, decoded, malformed
radartracker_records_total                 counter  ``outcome``: cat048_records, cat021_records,
                                                    records_to_tracker, cat048_unknown_sac_sic, …
radartracker_tracker_inputs_total          counter  ``reason``: the TrackManager's accounting
                                                    (plots_used, adsb_used, plots_late, …)
radartracker_cat062_total                  counter  ``what``: records, datagrams_sent, publications, …
radartracker_queue_depth                   gauge    datagrams waiting for the tracker
radartracker_queue_capacity                gauge    the bound of that queue
radartracker_tracks                        gauge    ``status``: tentative, confirmed, coasting
radartracker_processing_latency_seconds    histo.   datagram receipt → its records handed to the tracker
radartracker_input_lateness_seconds        histo.   per record: the newest record time received before it
                                                    − its time (how out of order the feed arrives: the
                                                    reorder window needed: only records later than
                                                    the window can be counted late)
radartracker_checkpoints_total             counter  ``outcome``: written (since start), skipped_busy, failed, superseded
=========================================  =======  ==================================================
"""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Histogram
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily

LATENCY_BUCKETS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 100.0, 300.0)
LATENESS_BUCKETS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0)


class ServiceMetrics:
    """A registry with the latency histogram and a collector reading the service's counters at scrape time."""

    def __init__(self, service) -> None:
        self.service = service
        self.registry = CollectorRegistry()
        self.latency = Histogram("radartracker_processing_latency_seconds",
                                 "Datagram receipt to its records handed to the tracker", buckets=LATENCY_BUCKETS,
                                 registry=self.registry)
        self.lateness = Histogram("radartracker_input_lateness_seconds",
                                  "Per record: newest record time received before it minus its time",
                                  buckets=LATENESS_BUCKETS, registry=self.registry)
        self.registry.register(self)

    def collect(self):
        view = self.service.view  # replaced whole by the tracker loop: a consistent copy
        yield _counter("radartracker_datagrams", "UDP datagrams by outcome", "outcome", view["datagrams"])
        yield _counter("radartracker_records", "ASTERIX records by outcome", "outcome", view["records"])
        yield _counter("radartracker_tracker_inputs", "TrackManager accounting of its inputs", "reason",
                       view["tracker"])
        yield _counter("radartracker_cat062", "CAT062 output", "what", view["published"])
        yield _counter("radartracker_checkpoints", "Checkpoints: written since start, skipped while one was "
                       "being written, failed", "outcome", view["checkpoints"])
        depth = GaugeMetricFamily("radartracker_queue_depth", "Datagrams waiting for the tracker")
        depth.add_metric([], self.service.queue.qsize())
        yield depth
        cap = GaugeMetricFamily("radartracker_queue_capacity", "Bound of the datagram queue")
        cap.add_metric([], self.service.queue.maxsize)
        yield cap
        yield _gauge("radartracker_tracks", "Live tracks by status", "status", view["tracks_by_status"])


def _counter(name: str, doc: str, label: str, values: dict) -> CounterMetricFamily:
    fam = CounterMetricFamily(name, doc, labels=[label])
    for k, v in sorted(values.items()):
        fam.add_metric([k], v)
    return fam


def _gauge(name: str, doc: str, label: str, values: dict) -> GaugeMetricFamily:
    fam = GaugeMetricFamily(name, doc, labels=[label])
    for k, v in sorted(values.items()):
        fam.add_metric([k], v)
    return fam
