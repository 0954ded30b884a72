"""The diagnosis: which physical effect a model is missing, and whether the survey can tell."""
