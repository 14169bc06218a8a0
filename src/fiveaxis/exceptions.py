"""The one exception type for bad user input: the command line prints its message as one line."""


def one_line(text) -> str:
    """text with line breaks and other control characters escaped (`\\n`), so that a message stays one line even
    when it quotes a file name, key or value that holds them."""
    text = str(text)
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(ValueError):
    """Bad input (machine file, measurement file, option): the message names file, row/key and what was expected.

    The message is kept on one line (control characters escaped), whatever the file names or values it quotes."""

    def __init__(self, message="", *args):
        super().__init__(one_line(message), *args)
