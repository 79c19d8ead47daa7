"""Estimation: the estimator contract, Kalman building blocks, plot-to-plane conversion, the coupling graph."""
