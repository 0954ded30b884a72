"""Term kinds: what a model is a sum of, each declared once in the registry with its parser, TOML form and capabilities."""
