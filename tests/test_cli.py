"""The command line: usage errors are one line and exit 2, like every other input error."""
import pytest

from fiveaxis.cli import COMMANDS, main


@pytest.mark.parametrize("argv", [
    ["table2", "--bogus"],
    ["nosuch"],
    ["gsa", "--le", "abc"],
    ["table2", "--latex", "--json"],
    ["derive", "--out"],
])
def test_usage_errors_are_one_line(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fiveaxis: error: ")


def test_every_command_has_help(capsys):
    for name in COMMANDS:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code == 0
        assert capsys.readouterr().out.startswith("usage: fiveaxis " + name)


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().out
