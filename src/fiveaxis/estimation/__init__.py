"""Estimation: the problem (design of a model and a measurement set), its design backends, identifiability, the fit, and the fitted-model record."""
