#!/usr/bin/env bash
# Make sure the real LinuxCNC can run here for `make test-linuxcnc`: the Debian package linuxcnc-uspace
# (LinuxCNC 2.9, with the system Python's `linuxcnc` and `hal` modules) and a non-root user to run it as (it
# refuses to run as root). Exit 0 when ready, 77 (with one line) when it cannot be installed here: the target
# then skips instead of failing.
set -euo pipefail
USER_NAME=${FIVEAXIS_LINUXCNC_USER:-cnc}
if ! command -v linuxcnc >/dev/null 2>&1 || ! /usr/bin/python3 -c "import linuxcnc, hal" >/dev/null 2>&1; then
    if ! command -v apt-get >/dev/null 2>&1 || [ "$(id -u)" -ne 0 ]; then
        echo "test-linuxcnc: skipped: LinuxCNC is not installed and apt-get is not available as root here" \
             "(install the Debian package linuxcnc-uspace)"
        exit 77
    fi
    echo "test-linuxcnc: installing linuxcnc-uspace (apt-get; log: /tmp/fiveaxis-linuxcnc-apt.log)"
    if ! { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y linuxcnc-uspace; } \
            > /tmp/fiveaxis-linuxcnc-apt.log 2>&1; then
        echo "test-linuxcnc: skipped: apt-get could not install linuxcnc-uspace (see /tmp/fiveaxis-linuxcnc-apt.log)"
        exit 77
    fi
fi
# halcompile (linuxcnc-uspace-dev) builds the kinematics module compensate writes (linuxcnc/volumetric/)
if ! command -v halcompile >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" -eq 0 ]; then
    echo "test-linuxcnc: installing linuxcnc-uspace-dev (halcompile; log: /tmp/fiveaxis-linuxcnc-apt.log)"
    { DEBIAN_FRONTEND=noninteractive apt-get install -y linuxcnc-uspace-dev || \
      { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y linuxcnc-uspace-dev; }; } \
        >> /tmp/fiveaxis-linuxcnc-apt.log 2>&1 || echo "test-linuxcnc: linuxcnc-uspace-dev not installed (its tests skip)"
fi
if [ "$(id -u)" -eq 0 ] && ! id "$USER_NAME" >/dev/null 2>&1; then
    useradd -m "$USER_NAME"
fi
echo "test-linuxcnc: $(dpkg-query -W -f='${Package} ${Version}' linuxcnc-uspace 2>/dev/null || echo linuxcnc)"
