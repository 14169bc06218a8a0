"""The one exception type for bad user input: the command line prints its message as one line."""


class InputError(ValueError):
    """Bad input (machine file, measurement file, option): the message names file, row/key and what was expected."""
