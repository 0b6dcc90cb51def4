"""sim_bus: the stand-in for the vehicle.

A farm-field simulator that produces what the real sensors put on the wires (IMU bridge CAN
frames, NMEA 0183 sentences) in the log formats of SPEC 3, with the truth beside it.
"""
