"""Effects: how an error (or the tool length) changes with a pose variable or time. One module per family (the
`Effect` protocol of `base`), the registry everything else asks (`families`), custom effects of the machine file."""
