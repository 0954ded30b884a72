"""A season: many surveys of one river fitted together from per-log sufficient statistics (docs/SEASON.md).

`stats` is the interface to the estimator, `tasks` the per-log work, `engine` where it runs (this process or
Dask), `frame` the common frame, `model` the season's models, `staleness` how long a map stays true, `run`
the whole pass and `output` what SEASON_DIR holds."""
