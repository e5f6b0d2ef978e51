#!/usr/bin/env bash
# Installs the example's npm packages (three, puppeteer-core: the versions pinned in
# package-lock.json) into examples/threejs/node_modules. puppeteer-core downloads no
# browser: the check drives Debian's /usr/bin/chromium (scripts/install-deps.sh).
# Skips `npm ci` when node_modules already holds exactly the locked versions.
set -euo pipefail
cd "$(dirname "$0")"
command -v npm >/dev/null || { echo "install.sh: npm is not installed (scripts/install-deps.sh installs it)" >&2; exit 1; }
stamp=node_modules/.package-lock.json   # npm's own record of what it installed
if [ -f "$stamp" ] && [ -d node_modules/three ] && [ -d node_modules/puppeteer-core ] \
   && node -e '
     const lock = require("./package-lock.json").packages, have = require("./node_modules/.package-lock.json").packages;
     for (const name of ["node_modules/three", "node_modules/puppeteer-core"])
       if (!have[name] || have[name].version !== lock[name].version) process.exit(1);' 2>/dev/null; then
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
