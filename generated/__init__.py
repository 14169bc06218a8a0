"""Generated numba kernels, one module per machine model. Written by `make derive`; never edit by hand."""
