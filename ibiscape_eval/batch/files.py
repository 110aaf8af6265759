"""Atomic output for the batch and report modules (temp file or folder, then rename).

The one place these modules take the project's atomic writer from; everything else imports
``atomic_write``, ``atomic_output_path`` and ``atomic_output_dir`` from here.
"""

from __future__ import annotations

from ibiscape_eval.io.atomic import atomic_output_dir, atomic_output_path, atomic_write

__all__ = ["atomic_output_dir", "atomic_output_path", "atomic_write"]
