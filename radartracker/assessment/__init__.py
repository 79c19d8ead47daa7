"""Surveillance performance assessment: each radar's biases, random errors, detection, codes and time
stamps, and the system tracks' ESASSP indicators, against a reference, judged by a profile
(docs/assessment.md).

``radartracker assess SCENARIO --out DIR`` writes ``report.html``, the tables as CSV and
``assessment.json``; from Python, :func:`radartracker.assessment.assess.assess`.
"""
