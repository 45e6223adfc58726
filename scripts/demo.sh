#!/usr/bin/env bash
# Quick-start command 1: install dependencies, build (Release), run the main job
# (the built-in BD-with-HI demo). Extra arguments go to `rpyfmm bd`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release > /dev/null
cmake --build --preset release --target rpyfmm_cli
./build/release/apps/rpyfmm bd "$@"
