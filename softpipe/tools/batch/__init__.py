"""Many frames: a job of frames rendered on a Dask cluster (or in this process), resumable.

Two parts, read in this order:

- :mod:`.job`, the **job format**: a job file (``[sweep]``, ``[[frames]]``, named models,
  materials and light sets) read and checked (:func:`load_job`, :func:`parse_job`,
  :func:`job_from_dict`; every mistake a :class:`JobError` naming the file, table and
  key) and its sweeps expanded into :class:`Frame` objects with stable, readable names.
- :mod:`.run`, the **run**: :func:`batch` renders the frames on a Dask ``LocalCluster``,
  a running cluster or in this process, writes each frame whole, keeps the manifest
  (``manifest.jsonl``) that lets a second run resume, and draws the contact sheet.

The module is callable: ``softpipe.batch(job, out_dir)`` is :func:`batch` (``softpipe``
imports this package on first use of ``softpipe.batch``; drawing does not need Dask).
On the command line: ``softpipe batch JOBS.toml -o DIR``. ``examples/sweep.toml``
explains every key of a job file; docs/batch.md is the guide.
"""
from __future__ import annotations

import sys
import types
from typing import Any

from softpipe.tools.batch.job import (
    BUILTIN_LIGHTS,
    MAX_JOB_FRAMES,
    MAX_NAME_LENGTH,
    VIEWS,
    Frame,
    Job,
    JobError,
    LightSet,
    as_job,
    job_from_dict,
    load_job,
    parse_job,
)
from softpipe.tools.batch.run import (
    CONTACT_SHEET,
    CONTACT_SHEET_MAX,
    CRASH_ONCE_ENV,
    MANIFEST,
    MAX_MANIFEST_LINE,
    BatchProgress,
    BatchResult,
    ClusterError,
    FrameRecord,
    batch,
    check_local_cluster,
    frame_params,
    local_worker_limit,
    read_manifest,
    render_frame,
)

__all__ = ["Frame", "Job", "JobError", "LightSet", "BatchProgress", "BatchResult", "FrameRecord", "load_job",
           "parse_job", "job_from_dict", "as_job", "batch", "render_frame", "read_manifest", "VIEWS",
           "BUILTIN_LIGHTS", "MAX_JOB_FRAMES", "MAX_NAME_LENGTH", "MANIFEST", "MAX_MANIFEST_LINE", "CONTACT_SHEET",
           "CONTACT_SHEET_MAX", "CRASH_ONCE_ENV", "ClusterError", "check_local_cluster", "frame_params",
           "local_worker_limit"]


class _CallableModule(types.ModuleType):
    """``import softpipe.tools.batch; softpipe.batch(job, out_dir)`` calls :func:`batch`."""

    def __call__(self, *args: Any, **kwargs: Any) -> BatchResult:
        return batch(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
