"""Reports: the paper's Tables 1-3 and run summaries (`tables`), Table 3 of several files side by
side (`compare`), and the paper's own values (`paper`).
Needs h5py and numpy only (never warp), so reports work without a device."""

from .compare import format_side_by_side
from .tables import (
    ReportError,
    Results,
    format_run_summary,
    format_tables,
    frictional_case,
    read_results,
    results_from_sweep,
)

__all__ = [
    "ReportError",
    "Results",
    "read_results",
    "results_from_sweep",
    "format_tables",
    "format_run_summary",
    "frictional_case",
    "format_side_by_side",
]
