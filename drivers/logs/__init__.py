"""The SPEC 3 log formats: candump -L for CAN, host-stamped NMEA 0183 lines."""
