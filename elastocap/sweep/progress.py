"""The sweep's progress objects: :mod:`elastocap.progress` (shared by every command)."""

from elastocap.progress import (
    NoProgress,
    Progress,
    TextProgress,
    TqdmProgress,
    make_progress,
)

__all__ = ["NoProgress", "Progress", "TextProgress", "TqdmProgress", "make_progress"]
