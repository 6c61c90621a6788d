#!/usr/bin/env bash
# Installs what legwork's tests need beyond Rust: Debian's `chromium`, for the headless
# browser test of the HTML replay (tests/replay_browser.rs). Idempotent: does nothing when
# `chromium` is already on PATH. Uses sudo only when not root. Prints what it did.
set -euo pipefail

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
"${SUDO[@]}" apt-get update -q
DEBIAN_FRONTEND=noninteractive "${SUDO[@]}" apt-get install -y -q --no-install-recommends chromium
echo "install-test-deps: installed $(chromium --version 2>/dev/null || echo chromium)"
