"""`fiveaxis dask --scheduler`: a bad address is a one-line error before anything starts (was ValueError)."""
import pytest

from conftest import run_cli
from fiveaxis.parallel import scheduler_address
from fiveaxis.exceptions import InputError


@pytest.mark.parametrize("text, expect", [
    ("garbage", "no port"),
    ("", "no port"),                  # was taken as "no scheduler": a local cluster started
    ("tcp://", "no port"),
    ("tcp://localhost", "no port"),
    ("tcp://localhost:abc", "port 'abc'"),
    ("tcp://localhost:0", "port '0'"),
    ("tcp://localhost:99999", "port '99999'"),
    ("tcp://:8786", "host name"),
    ("tcp://a b:8786", "host name"),
    ("inproc://x", "unknown scheme 'inproc'"),
    ("http://h:80", "unknown scheme 'http'"),
    ("tcp://[::1", "IPv6"),
    ("tcp://[::1]8786", "IPv6"),
    ("tcp://h:1\n2", "port"),
    ("tcp://h:1\n", "port"),
    ("\u00e9:1", "host name"),
])
def test_bad_scheduler_addresses(capsys, text, expect):
    with pytest.raises(InputError, match=expect):
        scheduler_address(text)
    assert run_cli("dask", "--scheduler", text, "--axis", "A=0:1:2", echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.startswith("fiveaxis: error: --scheduler: ") and err.count("\n") == 1 and expect in err


@pytest.mark.parametrize("text, address", [
    ("tcp://10.0.0.5:8786", "tcp://10.0.0.5:8786"),
    ("10.0.0.5:8786", "tcp://10.0.0.5:8786"),
    (" scheduler-1.cluster.local:8786 ", "tcp://scheduler-1.cluster.local:8786"),
    ("tcp://[::1]:8786", "tcp://[::1]:8786"),
    ("tls://h:8786", "tls://h:8786"),
])
def test_good_scheduler_addresses(text, address):
    assert scheduler_address(text) == address
