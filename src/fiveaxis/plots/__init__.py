"""PNG plots (matplotlib, Agg backend): one module per subject (sensitivity, residuals)."""
