#!/usr/bin/env bash
# Installs what legwork's tests need beyond Rust: Debian's `chromium`, for the headless
# browser test of the HTML replay (tests/replay_browser.rs), and the MuJoCo checker's
# Python environment (scripts/install-mujoco.sh, for tests/mujoco_check.rs). Idempotent:
# does nothing for what is already there. Uses sudo only when not root; apt-get waits (up
# to 5 minutes, scripts/apt-wait.sh) for another package manager's locks instead of failing. Prints what it did.
set -euo pipefail

bash "$(dirname "$0")/install-mujoco.sh"

if command -v chromium >/dev/null 2>&1; then
    echo "install-test-deps: chromium already installed ($(command -v chromium)); nothing to do"
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-test-deps: chromium is missing and apt-get is not available;" >&2
    echo "install-test-deps: install a Chromium that provides a 'chromium' command by hand" >&2
    exit 1
fi

SUDO=()
if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1; then
        SUDO=(sudo)
    else
        echo "install-test-deps: not root and no sudo: cannot run apt-get" >&2
        exit 1
    fi
fi

echo "install-test-deps: chromium not found; installing Debian's chromium with apt-get"
source "$(dirname "$0")/apt-wait.sh"
apt_get update -q
apt_get install -y -q --no-install-recommends chromium
echo "install-test-deps: installed $(chromium --version 2>/dev/null || echo chromium)"
