"""How good a model is: cross-validation folds, error metrics, the paired test between two models, and where a model fails."""
