"""navgw gateway: fusion loop, estimators, output encoding, address claim, service and CLI."""

__version__ = "0.1.0"
