"""The 15-state loosely coupled GNSS/INS error-state EKF (Gu et al.)."""
