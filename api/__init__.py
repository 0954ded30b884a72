"""forcemap's Python API, for notebooks and scripts: the same code the command line runs.

    import forcemap
    survey = forcemap.read_survey("survey.csv")       # CSV, Parquet or an MCAP log
    fit = survey.fit("current_speed", effects=["depth"])
    fit.cv_rmse, fit.diagnose()
    ds = fit.to_xarray(resolution=5)                  # needs forcemap[gis]

See docs/API.md.
"""

from forcemap.host.api import Fit, Survey, read_survey

__all__ = ["Fit", "Survey", "read_survey"]
