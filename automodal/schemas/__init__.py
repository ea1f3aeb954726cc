"""JSON Schemas of automodal's files, shipped as package data (plain files for any language).

``report-v1.schema.json`` is the report of ``docs/report.md`` (version 1). automodal itself
never loads it (no runtime dependency on a validator); the tests check every report they
make against it with ``jsonschema``. See :mod:`automodal.report_model` for the decision.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["REPORT_V1"]

REPORT_V1 = Path(__file__).with_name("report-v1.schema.json")
"""Path of the JSON Schema of the report, version 1."""
