#!/usr/bin/env bash
# Installs the Debian packages the EtherCAT tests build with, when they are
# missing: cmake, g++, nlohmann-json3-dev, libtinyxml2-dev (the same the vendored
# ../shared/vendor/kickcat/build.sh needs). As root it runs apt-get; otherwise it
# names what is missing and exits 1. Nothing is done when all are present.
# Usage: system-packages.sh [WHO]   (WHO prefixes the message, e.g. "plant-drive build")
set -euo pipefail
who=${1:-system-packages}
missing=()
command -v cmake >/dev/null || missing+=(cmake)
command -v g++ >/dev/null || missing+=(g++)
[ -f /usr/share/cmake/nlohmann_json/nlohmann_jsonConfig.cmake ] || [ -d /usr/include/nlohmann ] || missing+=(nlohmann-json3-dev)
[ -f /usr/include/tinyxml2.h ] || missing+=(libtinyxml2-dev)
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" != 0 ]; then
  echo "$who: install ${missing[*]} first (run tools/scripts/system-packages.sh as root)" >&2
  exit 1
fi
# One installer at a time: parallel test binaries may all find the packages missing.
exec 9>/tmp/exo-system-packages.lock
flock 9
missing_now=()
for p in "${missing[@]}"; do
  case $p in
    cmake|g++) command -v "$p" >/dev/null || missing_now+=("$p") ;;
    nlohmann-json3-dev) [ -d /usr/include/nlohmann ] || missing_now+=("$p") ;;
    libtinyxml2-dev) [ -f /usr/include/tinyxml2.h ] || missing_now+=("$p") ;;
  esac
done
[ ${#missing_now[@]} -eq 0 ] && exit 0
echo "$who: installing ${missing_now[*]} with apt-get" >&2
if ! (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing_now[@]}") >/dev/null 2>/tmp/exo-system-packages.err; then
  echo "$who: apt-get could not install ${missing_now[*]}:" >&2
  cat /tmp/exo-system-packages.err >&2
  exit 1
fi
