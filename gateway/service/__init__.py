"""The live service: the asyncio loop, its buses and serial port, sd_notify, input recording."""
