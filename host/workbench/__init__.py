"""The modelling workbench: fit map models to a samples table, cross-validate, diagnose missing effects."""

from forcemap.host.workbench.errors import WorkbenchError

__all__ = ["WorkbenchError"]
