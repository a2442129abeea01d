#!/usr/bin/env bash
# Install headless Chromium (Debian packages chromium and chromium-driver) for the HTML report's
# browser test (tests/test_report.py). Idempotent: does nothing when chromium is already there.
# Never fails the build: when it cannot install (not root, no apt-get, no network to the Debian
# mirror), it says why and exits 0; the browser test then skips with a clear message.
set -u

have_chromium() {
    command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1
}

if have_chromium; then
    echo "install_browser: chromium already installed ($(command -v chromium || command -v chromium-browser))"
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_browser: no apt-get on this machine; the browser test of the HTML report will skip"
    exit 0
fi
if [ "$(id -u)" != "0" ]; then
    echo "install_browser: not root, cannot apt-get install chromium; the browser test of the HTML report will skip"
    exit 0
fi
echo "install_browser: installing the Debian packages chromium and chromium-driver ..."
export DEBIAN_FRONTEND=noninteractive
if ! apt-get update -qq >/dev/null 2>&1; then
    echo "install_browser: apt-get update failed; the browser test of the HTML report will skip"
    exit 0
fi
if ! apt-get install -y -qq --no-install-recommends chromium chromium-driver >/dev/null 2>&1; then
    echo "install_browser: apt-get install chromium chromium-driver failed; the browser test will skip"
    exit 0
fi
if have_chromium; then
    echo "install_browser: chromium installed: $(chromium --version 2>/dev/null || true)"
else
    echo "install_browser: chromium still not found after the install; the browser test will skip"
fi
exit 0
