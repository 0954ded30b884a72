"""The estimator: Bayesian linear regression in a sum of terms' features, its hyperparameters by type-II maximum likelihood, and the numerical tables under it."""
