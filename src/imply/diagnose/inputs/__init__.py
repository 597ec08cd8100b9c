"""Stage 1 of the diagnostic, what is read: a push log and what a lab records beside it, checked cell by cell.

In: files (CSV or parquet). Out: a :class:`~imply.diagnose.inputs.pushlog.PushLog` (one entry per push), with the
boxes' tracks (:mod:`~imply.diagnose.inputs.track_file`) and calibration probes
(:mod:`~imply.diagnose.inputs.probes`) where the log has them, and :class:`~imply.diagnose.inputs.observables.Observables`
(which of them a fit reads). A bad cell is refused with its row and column; nothing is fitted here.
"""
