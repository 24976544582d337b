#!/usr/bin/env bash
# Builds the portable wheel of scripts/wheel.sh inside Debian 11 (glibc 2.31, GCC 10). Its module
# (libstdc++ linked in, libm's log and pow at their oldest version: CRUSHDEM_MANYLINUX) and the
# libgomp copied into the wheel then use no glibc symbol newer than 2.17, and auditwheel tags it
# manylinux2014 (manylinux_2_17): it installs on CentOS/RHEL 7, RHEL/Rocky 8, Ubuntu 18.04 and
# newer systems.
#  - Debian 11 is installed by debootstrap into ROOT (default build-wheel/debian11; kept, so a
#    second call only builds), from Debian's own mirror;
#  - CPython 3.11 and 3.13 are built there from Debian's sources of them (the upstream
#    tarballs, checked against their SHA-256), as Debian 11 ships 3.9: two wheels, one for
#    CPython 3.11 (cp311) and one for 3.12 and every later CPython (cp312-abi3: the stable ABI,
#    nanobind's STABLE_ABI, built with 3.13);
#  - toml++ and CLI11 are header-only: Debian 12's packages (Debian 11 has no toml++ and CLI11
#    1.9) are unpacked into ROOT;
#  - where the host has the CUDA toolkit (/usr/local/cuda), it is mounted into ROOT, and the
#    wheel carries the CUDA backend, its runtime linked in, as scripts/wheel.sh says.
# The source is the checkout's tracked and untracked files (not the ignored ones), copied into
# ROOT. Needs root (debootstrap, chroot, mount) and a Debian host (apt-get download).
# Usage: sudo bash scripts/wheel_debian11.sh [ROOT]   (prints the wheels' paths last)
# Check them there: sudo bash scripts/wheel_debian11.sh --check [ROOT] runs scripts/wheel_check.sh
# on the newest wheel of each tag that it built, inside ROOT, on glibc 2.31, with the
# CPython each is for.
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
root=$(realpath -m "${1:-build-wheel/debian11}")
[ "$(id -u)" = 0 ] || { echo "scripts/wheel_debian11.sh needs root (debootstrap, chroot)" >&2; exit 2; }
source scripts/deps.sh
apt_install_missing debootstrap

# CPython SERIES: VERSION, the Debian release whose source it is, its orig tarball's SHA-256.
pythons=("3.11 3.11.2 bookworm 2411c74bda5bbcfcddaf4531f66d1adc73f247f529aee981b029513aefdbf849 gz"
         "3.13 3.13.5 trixie 93e583f243454e6e9e4588ca2c2662206ad961659863277afcdb96801647d640 xz")

in_root() {  # runs a command in ROOT with a clean environment (but the host's proxy)
  local proxy=()
  for v in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY; do
    [ -n "${!v:-}" ] && proxy+=("$v=${!v}")
  done
  # pip trusts its own list of authorities unless told to use the system's.
  chroot "$root" /usr/bin/env -i HOME=/root LANG=C.UTF-8 "${proxy[@]}" \
    PIP_CERT=/etc/ssl/certs/ca-certificates.crt SSL_CERT_FILE=/etc/ssl/certs/ca-certificates.crt \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin "$@"
}

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount "${mounted[i]}" || true; done
}
trap cleanup EXIT
mount_in_root() {  # mount_in_root ARGS... TARGET (TARGET inside ROOT)
  local target=${*: -1}
  mkdir -p "$target"
  mountpoint -q "$target" || { mount "$@"; mounted+=("$target"); }
}

if [ ! -f "$root/etc/debian_version" ] || ! grep -q '^11\.' "$root/etc/debian_version"; then
  echo "# debootstrap Debian 11 into $root" >&2
  debootstrap --variant=minbase --include=build-essential,ninja-build,git,ca-certificates,\
libssl-dev,zlib1g-dev,libffi-dev,libbz2-dev,liblzma-dev,libsqlite3-dev,uuid-dev,cmake,\
libgtest-dev,patchelf,binutils,qemu-user \
    bullseye "$root" http://deb.debian.org/debian >&2
fi
cp /etc/resolv.conf "$root/etc/resolv.conf"
# The host's own certificate authorities (a proxy's, say) are trusted in ROOT as on the host.
if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
  cp /usr/local/share/ca-certificates/*.crt "$root/usr/local/share/ca-certificates/"
  in_root update-ca-certificates >/dev/null
fi
mount_in_root -t proc proc "$root/proc"
# POSIX semaphores (sem_open) live in /dev/shm: without it CPython's configure leaves out
# multiprocessing's SemLock, and dask's process pools (the sweep and calibration tests) fail.
mount_in_root -t tmpfs tmpfs "$root/dev/shm"

has_semlock() {  # has_semlock SERIES: ROOT's CPython SERIES exists and has multiprocessing's SemLock
  in_root "/opt/python$1/bin/python$1" -c "from _multiprocessing import SemLock"
}
for entry in "${pythons[@]}"; do
  read -r series version release sha256 compression <<<"$entry"
  # Built before, and with SemLock (an earlier build without /dev/shm lacks it: built again).
  has_semlock "$series" 2>/dev/null && continue
  echo "# building CPython $version ($release's source) in $root" >&2
  tarball="$root/src/python${series}_$version.orig.tar.$compression"
  mkdir -p "$root/src"
  [ -f "$tarball" ] || curl -fsSL -o "$tarball" \
    "http://deb.debian.org/debian/pool/main/p/python$series/$(basename "$tarball")"
  echo "$sha256  $tarball" | sha256sum -c --quiet
  rm -rf "$root/src/Python-$version"
  tar -xf "$tarball" -C "$root/src"
  in_root /bin/bash -c "cd /src/Python-$version && ./configure --prefix=/opt/python$series \
    --with-ensurepip=install >/dev/null && make -j$(nproc) >/dev/null && make install >/dev/null"
  has_semlock "$series" || {
    echo "CPython $version in $root has no multiprocessing SemLock (is /dev/shm a tmpfs there?)" >&2
    exit 1
  }
  rm -rf "$root/src/Python-$version"  # installed in /opt: the build tree (about 0.5 GB) goes
done

if [ ! -f "$root/usr/include/toml++/toml.h" ] || [ ! -f "$root/usr/include/CLI/CLI.hpp" ]; then
  debs=$(mktemp -d)
  (cd "$debs" && apt-get download libtomlplusplus-dev libcli11-dev >&2)
  for d in "$debs"/*.deb; do dpkg-deb -x "$d" "$root"; done
  rm -rf "$debs"
fi

if [ -x /usr/local/cuda/bin/nvcc ]; then
  cuda=$(realpath /usr/local/cuda)
  mount_in_root --bind "$cuda" "$root$cuda"
  mount -o remount,bind,ro "$root$cuda"
  ln -sfn "$cuda" "$root/usr/local/cuda"
fi

src=/work/crushdem
if [ "$check" = 1 ]; then
  cp scripts/wheel_check.sh scripts/deps.sh "$root$src/scripts/"
  for tag in cp311-cp311 cp312-abi3; do
    # The newest wheel of the tag that this script built (ROOT's copy of dist/ holds no other).
    wheel=$(ls -t "$root$src"/dist/crushdem_sand-*-$tag-manylinux*.whl | head -1)
    series=$([ $tag = cp311-cp311 ] && echo 3.11 || echo 3.13)
    in_root /bin/bash -c "cd $src && ldd --version | head -1 && \
      PYTHON=/opt/python$series/bin/python$series bash scripts/wheel_check.sh \
      dist/$(basename "$wheel")"
  done
  exit
fi

echo "# copying the checkout into $root$src" >&2
rm -rf "$root$src"
mkdir -p "$root$src"
git ls-files -z --cached --others --exclude-standard | while IFS= read -r -d '' f; do
  [ -e "$f" ] && printf '%s\0' "$f"
done | tar --null -T - -cf - | tar -xf - -C "$root$src"

# A CMake from PyPI (scikit-build-core fetches it): Debian 11's 3.18 predates CUDA 13.
# The copy has no .git: the commit that runs record (cmake/build_info.cmake) comes along.
commit=$(git describe --always --dirty --abbrev=12 --exclude "*" 2>/dev/null || echo unknown)
mkdir -p dist
for series in 3.11 3.13; do
  # scripts/wheel.sh's .venv is made with the CPython it builds for.
  in_root /bin/bash -c "cd $src && rm -rf .venv && PATH=/usr/local/cuda/bin:\$PATH \
    PYTHON=/opt/python$series/bin/python$series CRUSHDEM_COMMIT=$commit \
    CRUSHDEM_WHEEL_PLAT=manylinux2014_x86_64 \
    SKBUILD_CMAKE_VERSION='>=3.25' bash scripts/wheel.sh >/dev/null"
done
for tag in cp311-cp311 cp312-abi3; do
  wheel=$(ls -t "$root$src"/dist/crushdem_sand-*-$tag-manylinux*.whl | head -1)
  cp "$wheel" dist/
  echo "dist/$(basename "$wheel")"
done
