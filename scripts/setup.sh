#!/usr/bin/env bash
# Idempotent set-up: system library for open3d, a virtualenv, and camtool
# installed editable with its test extra. A second run installs nothing.
set -euo pipefail
cd "$(dirname "$0")/.."

# open3d 0.20 needs Debian's libusb-1.0-0 at import time.
if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "setup: installing Debian package libusb-1.0-0 (needed by open3d)"
    apt-get update -qq >/dev/null && apt-get install -y -qq libusb-1.0-0 >/dev/null
  else
    echo "setup: open3d needs libusb-1.0-0: run 'sudo apt-get install libusb-1.0-0' and retry" >&2
    exit 2
  fi
fi

# The report.html browser test opens the page in a headless chromium (Debian's package); optional:
# without it that one test skips.
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1 \
    && [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
  echo "setup: installing Debian package chromium (headless browser for the report.html test)"
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium; } \
    >/dev/null 2>&1 || echo "setup: chromium could not be installed; the report.html browser test will skip" >&2
fi

if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi

stamp=.venv/.setup-stamp
want="$(sha256sum pyproject.toml | cut -c1-16)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
  exit 0
fi
echo "setup: installing camtool and its dependencies into .venv"
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[test]"
# compile the planner's numba kernels once, so the first job does not pay for it
.venv/bin/python -c "import camtool.plan.kernel as k; k.warm_up()" || true
echo "$want" > "$stamp"
