"""The replay pipeline: a scenario through association, filters and estimator to results, evaluation and figures."""
