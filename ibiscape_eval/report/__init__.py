"""Tables and figures for results (matplotlib imported lazily inside the plot functions)."""

from .tables import format_drift_table, format_error_table, format_header

__all__ = ["format_drift_table", "format_error_table", "format_header"]
