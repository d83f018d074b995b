#!/usr/bin/env bash
# Run the whole test suite on a fresh machine: installs the system servers and the browser the
# tests start themselves (mosquitto, redis-server, influxd, chromium) and ROS 2's test
# interface files, the Python packages into
# .venv, then runs ruff and pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
for pkg_bin in mosquitto:mosquitto redis-server:redis-server influxdb:influxd chromium:chromium; do
    pkg=${pkg_bin%%:*}; bin=${pkg_bin##*:}
    command -v "$bin" >/dev/null 2>&1 || [ -x "/usr/sbin/$bin" ] || need+=("$pkg")
done
# ROS 2's own test_msgs definitions (no ROS install): the type store's corpus in tests/ros2
[ -d /usr/share/test_interface_files ] || need+=(ros2-test-interface-files)
if [ ${#need[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ]; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
    else
        echo "warning: missing system packages ${need[*]} (run as root to install them)" >&2
    fi
fi
# The tests start their own servers on free loopback ports; stop the ones the packages start.
for svc in mosquitto redis-server influxdb; do
    command -v service >/dev/null 2>&1 && service "$svc" stop >/dev/null 2>&1 || true
done
bash scripts/setup.sh test
.venv/bin/ruff check rasm tests benchmarks examples
.venv/bin/python -m pytest "$@"
