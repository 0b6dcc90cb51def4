"""Offline processing of SPEC 3 logs: replay through the same fusion core."""
