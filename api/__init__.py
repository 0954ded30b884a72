"""forcemap's Python API, for notebooks and scripts: the same code the command line runs.

    import forcemap
    survey = forcemap.read_survey("survey.csv")       # CSV, Parquet or an MCAP log
    fit = survey.fit("current_speed", effects=["depth"])
    fit.cv_rmse, fit.diagnose()
    ds = fit.to_xarray(resolution=5)                  # needs forcemap[gis]

See docs/API.md.

The names load on first use, so that importing a subpackage (`forcemap.host.cli`, which the `forcemap`
command starts from) loads no numpy before the command has set its BLAS threads
(host/workbench/engine/threads.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from forcemap.host.api import Fit, Survey, read_survey

__all__ = ["Fit", "Survey", "read_survey"]


def __getattr__(name: str):
    if name in __all__:
        from forcemap.host import api

        return getattr(api, name)
    raise AttributeError(f"module 'forcemap' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
