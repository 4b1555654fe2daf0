"""Estimators and measured-data handling: least squares, recursive least squares, Kalman fusion."""
