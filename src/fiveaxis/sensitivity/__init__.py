"""Sensitivity: LSIL and GSIL (Li et al. 2018), grids, toolpaths, surfaces, the paper's setups and experiments, Sobol' indices."""
