"""Errors of the job layer."""

from __future__ import annotations

from mbctl.exceptions import ToolkitError


class JobError(ToolkitError):
    """Base class of the job runner's errors."""


class OutputError(JobError):
    """The output folder cannot be created or written, or another run holds it."""
