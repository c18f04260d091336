#!/usr/bin/env bash
# Install Debian's chromium for the dashboard's headless browser test (test/test_dashboard_browser.py).
# As root: installs it with apt-get when missing. Otherwise: prints how to install it and exits 0
# (the browser test then skips with that reason).
set -euo pipefail

find_chromium() {
    for name in chromium chromium-browser google-chrome google-chrome-stable; do
        if command -v "$name" >/dev/null 2>&1; then
            command -v "$name"
            return 0
        fi
    done
    return 1
}

if path=$(find_chromium); then
    echo "chromium found: $path ($("$path" --version 2>/dev/null || echo 'version unknown'))"
    exit 0
fi

if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing chromium with apt-get ..."
    apt-get update
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium fonts-dejavu-core
    path=$(find_chromium)
    echo "chromium installed: $path ($("$path" --version 2>/dev/null || true))"
else
    echo "chromium is not installed. To run the dashboard's browser test, install it, e.g.:"
    echo "    sudo apt-get update && sudo apt-get install -y chromium"
    echo "(test/test_dashboard_browser.py skips until then)"
fi
exit 0
