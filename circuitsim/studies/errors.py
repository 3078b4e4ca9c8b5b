"""The studies' typed errors."""

from __future__ import annotations


class StudyError(ValueError):
    """A study cannot be set up: a bad grid, a parameter that cannot vary, a scheduler
    address that is not one. The message names the file, line, column or option."""


class GridFileError(StudyError):
    """A grid CSV file that cannot be used; the message names the file, line and column."""


class ClusterError(RuntimeError):
    """The cluster could not run the study: the scheduler is unreachable, dask distributed
    is not installed, or a batch failed on every retry (the message names its variants)."""
