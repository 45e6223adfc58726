#!/usr/bin/env bash
# Quick-start command 2: install dependencies, build (Release), run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release
cmake --build --preset release
ctest --preset release "$@"
