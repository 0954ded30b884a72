"""A survey read and prepared: the samples table in a local frame, clean columns, bridged gaps, spikes, the rows each target has, the instruments it names, and the log's own data problems."""
