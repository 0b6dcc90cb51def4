"""``navgw fleet``: many recordings replayed on a Dask cluster, one table row each.

The pure parts find recordings (:mod:`.recordings`, :mod:`.manifest`), tally a replay's inputs
(:mod:`.input_tally`) and make a row from a replay's summary and output log (:mod:`.rows`,
:mod:`.agreement`); :mod:`.task` is the unit of work a worker runs, :mod:`.cluster` the Dask
shell, :mod:`.table` and :mod:`.histograms` the results. Off-vehicle: the ``fleet`` extra.
"""
