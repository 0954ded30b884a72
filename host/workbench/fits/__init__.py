"""A fit and what it leaves: fit a target, record it in the survey's workspace, and draw its residuals."""
