"""Many recordings at once (``gait-biofeedback batch``): :mod:`.sessions` finds them and names each,
:mod:`.task` analyses one (``analyze`` and ``report``, the same core as one session), :mod:`.table`
writes the cohort table, :mod:`.run` spreads the tasks over Dask distributed workers."""
