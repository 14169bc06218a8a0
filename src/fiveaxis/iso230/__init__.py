"""The figures of ISO 230-2 (positioning of a linear axis), ISO 230-9's simplified uncertainty of them, and
ISO 230-4 (circular tests), from measurement files; `positioning`, `uncertainty`, `circular`."""
