"""Effects: how an error (or the tool length) changes with a pose variable or time; the grammar of their ids, the families, custom effects and the whitelist of their expressions."""
