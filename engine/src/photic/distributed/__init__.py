"""Distributed rendering on Dask: jobs of many scenes, frames and swept parameters.

A render splits into work units (``units``: band group x sensor x run of passes, cameras
optionally in tiles, and rounds for a target standard error) with deterministic seeds; each
unit's sums and sums of squares are stored as they complete (``store``) and merged exactly
in a fixed order, so the outputs do not depend on where or when units ran. ``runner`` runs a
job (``job``: the job file) on a ``dask.distributed`` cluster (local by default) or in this
process. Command line: ``photic batch JOB``; documentation: docs/distributed.md.
"""
from .job import Item, Job, JobError, load_job, parse_job, scene_job
from .runner import BatchReport, BatchStopped, SchedulerError, check_scheduler_address, run_job
from .units import CameraPreview, ItemMerger, Unit, compute_unit, merge_order, plan_round

__all__ = ["Item", "Job", "JobError", "load_job", "parse_job", "scene_job", "BatchReport",
           "BatchStopped", "SchedulerError", "check_scheduler_address", "run_job", "CameraPreview", "ItemMerger", "Unit", "compute_unit",
           "merge_order", "plan_round"]
