"""The functional core: one engine, the output guard and the encoders wired, fed samples."""
