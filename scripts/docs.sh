#!/usr/bin/env bash
# Builds the docs site into build/site: runs the notebooks of notebooks/ unless build/notebooks/
# holds current executed copies (tests/python/test_notebooks.py leaves them there), then
# `mkdocs build --strict`, which fails on a broken link, a missing anchor or a page left out of
# the nav (mkdocs.yml, scripts/mkdocs_hooks.py). docs/api.md is shown as committed;
# tests/python/test_docs.py checks that it is what scripts/api_reference.py generates.
# Usage: bash scripts/docs.sh            (from the repository root; after scripts/test.sh, or
#        with crushdem installed in .venv)
#        bash scripts/docs.sh serve      (the same, then a live preview on http://127.0.0.1:8000)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/deps.sh
ensure_venv
py=.venv/bin/python

if ! "$py" -c "import crushdem_sand" 2>/dev/null; then
  echo "== Docs: crushdem is not installed in .venv: installing it with the docs extra"
  "$py" -m pip install --quiet ".[docs]"
else
  # The docs tools alone (the extra's packages without rebuilding crushdem).
  mapfile -t reqs < <("$py" - <<'EOF'
import tomllib
extras = tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]
def expand(name, seen=set()):
    for req in extras[name]:
        if req.startswith("crushdem-sand["):
            for sub in req[len("crushdem-sand["):-1].split(","):
                if sub not in seen:
                    seen.add(sub)
                    yield from expand(sub.strip())
        else:
            yield req
print("\n".join(dict.fromkeys(expand("docs"))))
EOF
)
  "$py" -m pip install --quiet "${reqs[@]}"
fi

start=$SECONDS
echo "== Docs: notebooks"
"$py" scripts/notebooks.py --if-stale
echo "== Docs: site (strict)"
if [ "${1:-}" = serve ]; then
  exec "$py" -m mkdocs serve --strict
fi
# Not --quiet: it hides the warnings from --strict, which then lets them pass.
"$py" -m mkdocs build --strict
echo "docs site in build/site/index.html ($((SECONDS - start)) s)"
