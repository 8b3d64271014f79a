"""Attitude from angular rates: the algorithm registry, batch and streaming integration, and the
attitude-stream policy (validation, gaps, resets, covariance) that the node and replay share."""
