#!/usr/bin/env bash
# Installs what lop's builds, tests and benchmarks need beyond the Rust toolchain, on Debian or
# Ubuntu. Idempotent: it only calls apt-get when something is missing.
#   tetgen    regenerates and checks the shipped meshes (assets/generate.py --check)
#   rt-tests  cyclictest, the machine's own wake-up latency floor in `lop-bench latency`
set -euo pipefail

need=()
command -v tetgen >/dev/null 2>&1 || need+=(tetgen)
command -v cyclictest >/dev/null 2>&1 || need+=(rt-tests)
command -v python3 >/dev/null 2>&1 || need+=(python3)

if [ ${#need[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "setup: please install: ${need[*]} (no apt-get here)" >&2
    exit 1
  fi
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${need[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
fi
