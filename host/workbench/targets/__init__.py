"""A model per survey target: scalars directly, wind and current through their components in a flow frame, and what every model of one survey shares."""
