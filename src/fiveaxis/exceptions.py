"""The one exception type for bad user input: the command line prints its message as one line."""


def one_line(text) -> str:
    """text with line breaks and other control characters escaped (`\\n`), so that a message stays one line even
    when it quotes a file name, key or value that holds them."""
    text = str(text)
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(ValueError):
    """Bad input (machine file, measurement file, option): the message names file, row/key and what was expected.

    The message is kept on one line (control characters escaped), whatever the file names or values it quotes.
    key: the keyword argument(s) of the library call that the message is about (a str or a tuple of them), spelled
    in the message as `key:`, `key=VALUE` or `key 'VALUE'`; the command line replaces them by its options."""

    def __init__(self, message="", *args, key=None):
        super().__init__(one_line(message), *args)
        #: the library argument(s) the message is about, as the message spells them (`damping`, `L0`, `force`):
        #: the command line names its option instead (fiveaxis.cli.OPTIONS).
        self.key = key
