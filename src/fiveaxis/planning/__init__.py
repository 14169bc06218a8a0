"""Measurement planning: which poses determine the most, before measuring."""
