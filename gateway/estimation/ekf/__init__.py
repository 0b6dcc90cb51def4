"""The loosely coupled (15 INS + 3 fix-error states) GNSS/INS error-state EKF (Gu et al.)."""
