"""The former name of :mod:`bitemesh.core.repair` (the valid domain: spurious cells out, the boundary repaired):
``from bitemesh.core.domain import carve_domain`` keeps working."""
from .repair import carve_domain, compact, repaired  # noqa: F401 (re-exported)
