"""The gateway's TOML configuration (SPEC 5): sections, schema checks, defaults."""
