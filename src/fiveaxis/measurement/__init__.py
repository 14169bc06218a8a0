"""Measurements: files, observation rows, setups (artefact placements), instruments and their standard plans, simulation."""
