"""Drivers: bytes and frames from the wires in, typed timestamped samples out."""
