"""Generic recursive estimators (unscented transform and Kalman filter) used by the attitude and heading filters."""
