# Sourced by the scripts: installs the build dependencies when they are missing (Debian 12).
apt_install_missing() {
  local missing=()
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "# installing Debian packages: ${missing[*]}" >&2
  local sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
}

ensure_build_deps() {
  command -v cmake >/dev/null && command -v g++ >/dev/null && [ -f /usr/include/gtest/gtest.h ] \
    && [ -f /usr/include/CLI/CLI.hpp ] && [ -f /usr/include/toml++/toml.h ] \
    || apt_install_missing cmake g++ make libgtest-dev libcli11-dev libtomlplusplus-dev
}

# A virtual environment in .venv with the Python build tools (PyPI).
ensure_venv() {
  local py=${PYTHON:-python3}
  if [ ! -x .venv/bin/python ]; then
    "$py" -m venv .venv 2>/dev/null || { apt_install_missing python3-venv; "$py" -m venv .venv; }
  fi
  .venv/bin/python -m pip install --quiet --upgrade pip >/dev/null
  # A checkout's own package installed before the distribution became crushdem-sand: its stale
  # `crushdem` package and command would linger beside the new ones, so it goes first (only when
  # it is ours: the unrelated crushdem of PyPI has no compiled _core).
  if .venv/bin/python -m pip show --files crushdem 2>/dev/null | grep -q "crushdem/_core"; then
    echo "# removing crushdem (this project before its distribution was named crushdem-sand)" >&2
    .venv/bin/python -m pip uninstall --quiet --yes crushdem >&2
  fi
}
