"""The pipeline: a scenario through association, track filters and bias estimator into one result.

``result = run(data, RunConfig(...))`` (:mod:`radartracker.pipeline.run`, :mod:`radartracker.pipeline.config`),
then ``write_outputs(result, folder)`` (:mod:`radartracker.pipeline.writer`); docs/architecture.md.
"""
