"""Estimators and measured-data handling: data loading and preprocessing, (weighted) least squares,
ARX/ARMAX, (extended) recursive least squares, Kalman fusion, the servo-arm joint model and its
metrics, and loaders for the shared real data sets."""
