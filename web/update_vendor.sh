#!/usr/bin/env bash
# Copies the viewer's front-end dependency, as pinned in package-lock.json, into the source tree,
# where CMake embeds it into the server: the server then needs neither Node nor the network.
# Run after changing the version in package.json (npm install updates the lockfile).
set -euo pipefail
cd "$(dirname "$0")"
[ -d node_modules/three ] || npm ci --no-audit --no-fund
vendor=../src/ffloc/server/viewer/vendor
mkdir -p "$vendor"
cp node_modules/three/build/three.module.min.js "$vendor/three.module.min.js"
cp node_modules/three/LICENSE "$vendor/three.LICENSE"
version=$(node -p "require('./node_modules/three/package.json').version")
echo "three $version (MIT), build/three.module.min.js, from the npm registry; see web/update_vendor.sh" \
  >"$vendor/README"
echo "vendored three $version into $vendor"
