"""Estimation: the engines and their pure helpers. No I/O, no asyncio, no clock of their own."""
