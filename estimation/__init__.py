"""Estimators and identification protocols: ARX/ARMAX, (extended) recursive least squares, Kalman fusion,
the servo-arm second-order joint model and its metrics, and loaders for the shared real data sets."""
