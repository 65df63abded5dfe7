"""One offline HTML page from a results folder: ``python -m bondid.report RESULTS_DIR``."""

from .build import REPORT_NAME, build_report, build_report_html, scan

__all__ = ["REPORT_NAME", "build_report", "build_report_html", "scan"]
