"""``navgw monitor``: the bus as a person reads it. A pure state model fed frame by frame
(:mod:`~gateway.monitor.bus_state`), its text (:mod:`~gateway.monitor.panels`), frame sources
(:mod:`~gateway.monitor.sources`) and the Textual app (:mod:`~gateway.monitor.app`)."""
