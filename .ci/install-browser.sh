#!/usr/bin/env bash
# Install Debian's chromium + chromium-driver for the headless-browser tests
# (tests/test_viz_meshcat.py screenshots the exported Meshcat page and the live viewer).
#
# Idempotent and quiet. Exits 0 when both are already installed, or when apt-get is not
# available (the browser tests then skip, with the reason shown in pytest's summary).
# Exits 1 if apt-get is there but the installation fails, so that a lost browser does not
# go unnoticed.
set -u

if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-browser: apt-get not available; browser tests will be skipped" >&2
    exit 0
fi

SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
        SUDO="sudo -n"
    else
        echo "install-browser: not root and no password-less sudo; browser tests will be skipped" >&2
        exit 0
    fi
fi

export DEBIAN_FRONTEND=noninteractive
log="$(mktemp)"
if ! { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq chromium chromium-driver; } >"$log" 2>&1; then
    echo "install-browser: installing chromium + chromium-driver failed:" >&2
    tail -n 20 "$log" >&2
    rm -f "$log"
    exit 1
fi
rm -f "$log"
command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1
