"""One module per ``navgw`` sub-command, each a thin layer over library functions."""
