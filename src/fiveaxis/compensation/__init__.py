"""Compensation: from the identified model to what a controller loads."""
