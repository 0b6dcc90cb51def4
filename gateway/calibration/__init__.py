"""Field calibration of the IMU mounting (issue 17): pure estimators fed timestamped samples.

No I/O and no clock of their own, like the engines: ``navgw calibrate`` feeds them recorded
logs, and the live service can feed them the same samples. Start at :mod:`.mounting`.
"""
