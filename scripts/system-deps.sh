#!/usr/bin/env bash
# Install the Debian packages the project needs, only when they are missing: headless MuJoCo
# rendering (EGL + Mesa's llvmpipe), and Chromium with a font for the web console's browser
# tests (Playwright drives the system's Chromium: its own browser download is not reachable
# everywhere), and the real PyKDL (python3-pykdl: `davinci-sim run` gives it to dVRK scripts,
# and the PyKDL subset is tested against it). Needs root (or sudo) the first time only.
set -euo pipefail
pkgs=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libglx-mesa0 chromium fonts-dejavu-core
      python3-pykdl)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
if ! command -v apt-get >/dev/null; then
  echo "system-deps: missing ${missing[*]} and no apt-get; install them with your package manager" >&2
  exit 1
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
echo "system-deps: installing ${missing[*]}"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
