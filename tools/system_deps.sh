#!/usr/bin/env bash
# Install the Debian packages the test suite needs, when they are missing and we are root.
# Off-screen rendering: libosmesa6. ROS 1 (the ROS node tests): rospy, rosmaster and messages.
set -euo pipefail

PACKAGES=(libosmesa6 python3-rospy python3-rosmaster python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-nav-msgs)

missing=()
for pkg in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done

if [ ${#missing[@]} -eq 0 ]; then
    exit 0
fi
if [ "$(id -u)" != 0 ]; then
    echo "system-deps: missing ${missing[*]} (not root, not installing; the tests that need them will skip)" >&2
    exit 0
fi
echo "system-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
