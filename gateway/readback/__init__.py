"""Reading navgw's output back (off-vehicle): any frame of a bus or log decoded by the DBC."""
