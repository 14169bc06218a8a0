"""Diagnosis: candidate effects, their searches, the decision, residual tests, separation advice."""
