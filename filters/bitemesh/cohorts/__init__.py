"""Cohorts: many cases meshed on dask.distributed, each by :func:`bitemesh.mesh` as ``bitemesh mesh`` meshes it
(``bitemesh batch``).

- :mod:`.cases`: the cases from files, folders, glob patterns or a manifest CSV; their hash and records;
- :mod:`.run`: the Dask driver, :func:`batch`;
- :mod:`.report`: summary.csv and report.html.

dask and distributed (``pip install "bitemesh[batch]"``) are imported only when :func:`batch` runs.
"""
from .run import COLUMNS, batch  # noqa: F401
