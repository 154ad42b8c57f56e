"""Batch mode: many jobs, each in its own process, on a local pool or on Dask.

``prepare_batch`` finds and checks the jobs, ``run_batch`` runs them on an
executor and returns one ``JobResult`` per job (sorted by job path), and
``write_summary`` writes OUTDIR/summary.json. See docs/batch.md.
"""
from .executors import run_batch
from .runner import JobResult, JobSpec, prepare_batch, run_one
from .summary import batch_exit_code, summary_dict, write_summary

__all__ = ["JobResult", "JobSpec", "prepare_batch", "run_batch", "run_one",
           "batch_exit_code", "summary_dict", "write_summary"]
