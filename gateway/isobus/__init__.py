"""The ISOBUS side: J1939 ids, ISO 11783-5 address claim, NMEA 2000 encoders, output timing."""
