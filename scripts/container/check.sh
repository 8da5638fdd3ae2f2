#!/usr/bin/env bash
# The container image, built from the Dockerfile and run, on a machine without a Docker
# daemon or a registry (docs/deployment.md, "The image in CI"):
#
#   bash scripts/container/check.sh
#
# 1. Local stand-ins of the Dockerfile's two base images, under the exact names of its FROM
#    lines (no registry is reachable here): the builder, Debian bookworm (minbase) with gcc,
#    libc6-dev, ca-certificates, cmake, make and nasm (libjpeg-turbo's build, which the
#    Dockerfile installs into the official image) and this machine's Rust toolchain laid out as the official
#    rust image lays it out (/usr/local/cargo, /usr/local/rustup, PATH, CARGO_HOME,
#    RUSTUP_HOME); the runtime, what distroless cc holds (libc6, libgcc-s1, libstdc++6,
#    libgomp1, libssl3, ca-certificates, tzdata, netbase, the user nonroot 65532), no shell.
#    Built with mmdebstrap and `podman import`; kept between runs (rebuilt when the toolchain
#    or this recipe changes, or with REFLECTANCE_CONTAINER_REBUILD_BASES=1).
# 2. `podman build --isolation=chroot --pull=never --format docker` of the Dockerfile as it
#    is, tagged localhost/reflectance:check. The Docker format keeps the HEALTHCHECK (OCI
#    has none). The layers stay in podman's cache between runs: only what changed is
#    rebuilt (cache images of earlier builds that nothing uses any more are pruned).
# 3. The image's configuration: user 65532, the exposed port is the port of
#    REFLECTANCE_LISTEN, entrypoint and command, health check, the shipped models (exactly
#    the files git tracks under each model's latest version, .dockerignore's), the data
#    directory owned by 65532, the size.
# 4. The image's root filesystem (podman export), its entrypoint run in it (chroot, uid and
#    gid 65532, no supplementary groups, no capabilities, the image's environment and working
#    directory, /proc and /dev mounted in a private mount namespace): the health check fails
#    with no server and passes with one; `serve` classifies the committed fixture
#    tests/fixtures/features/sphere_rgb8.png as chrome; with an admin token, a render job
#    writes into the data directory; then the server stops on SIGTERM, and no file outside
#    the data directory was created, changed or removed.
#
# Exits non-zero on any failure. Runs as root (podman, chroot, mounts); installs podman,
# mmdebstrap, uidmap, jq and curl with apt-get when they are missing.
#
# Environment: REFLECTANCE_CONTAINER_CACHE (default /var/cache/reflectance-container),
# REFLECTANCE_CONTAINER_REBUILD_BASES=1, REFLECTANCE_CONTAINER_NO_CACHE=1 (podman build
# --no-cache: a cold build), DEBIAN_MIRROR, DEBIAN_SECURITY_MIRROR.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
SELF="$ROOT/scripts/container/check.sh"
cd "$ROOT"

TAG=localhost/reflectance:check
CACHE=${REFLECTANCE_CONTAINER_CACHE:-/var/cache/reflectance-container}
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
SECURITY_MIRROR=${DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}
# Changes when the stand-ins' recipe below changes: images built by an older recipe are
# rebuilt.
RECIPE=5
FIXTURE=tests/fixtures/features/sphere_rgb8.png

die() { echo "container check: $*" >&2; exit 1; }
say() { echo "== $*"; }

# ---------------------------------------------------------------------------------------
# mmdebstrap hooks (run as `check.sh hook-… ROOTFS`, on the host, with the root as $1).

# The rust image's layout: rustup and its proxies in /usr/local/cargo/bin, the toolchain in
# /usr/local/rustup/toolchains/<version>-<host> as the default, everything writable by all
# (the official image's `chmod -R a+w`). Without the toolchain's documentation (the image's
# minimal profile has none).
hook_builder() {
  local root=$1 cargo=$1/usr/local/cargo rustup=$1/usr/local/rustup
  mkdir -p "$cargo/bin" "$rustup/toolchains" "$rustup/update-hashes"
  tar -C "$STANDIN_SYSROOT" --exclude=./share/doc -cf - . \
    | tar -C "$rustup/toolchains" --one-top-level="$STANDIN_TOOLCHAIN" -xf -
  install -m 755 "$STANDIN_RUSTUP" "$cargo/bin/rustup"
  local proxy
  for proxy in cargo cargo-clippy cargo-fmt cargo-miri clippy-driver rls rust-analyzer \
      rust-gdb rust-gdbgui rust-lldb rustc rustdoc rustfmt; do
    ln "$cargo/bin/rustup" "$cargo/bin/$proxy"
  done
  printf 'version = "12"\ndefault_toolchain = "%s"\nprofile = "minimal"\n\n[overrides]\n' \
    "$STANDIN_TOOLCHAIN" >"$rustup/settings.toml"
  chmod -R a+w "$cargo" "$rustup"
}

# What distroless cc-debian12:nonroot holds: the libraries, certificates, time zones,
# passwd and group with root, nobody and nonroot (65532), /home/nonroot, /tmp; no shell, no
# package manager, no documentation.
hook_runtime() {
  local r=$1
  # The certificate bundle update-ca-certificates would write (distroless ships only that).
  mkdir -p "$r/etc/ssl/certs"
  local crt
  for crt in "$r"/usr/share/ca-certificates/mozilla/*.crt; do
    cat "$crt"
    [ -z "$(tail -c 1 "$crt")" ] || echo
  done >"$r/etc/ssl/certs/ca-certificates.crt"
  # What the packages' dependencies (debconf, perl-base, mawk, openssl) brought and distroless
  # leaves out.
  rm -rf "$r"/usr/share/{doc,man,info,lintian,locale,perl5,debconf,ca-certificates,bug,menu} \
    "$r"/usr/lib/x86_64-linux-gnu/perl-base "$r"/usr/lib/x86_64-linux-gnu/perl "$r"/usr/bin/* \
    "$r"/usr/sbin/* "$r"/etc/alternatives/* "$r"/var/cache/debconf "$r"/var/cache/apt \
    "$r"/var/lib/apt "$r"/var/log/* "$r"/etc/ca-certificates* "$r"/etc/ssl/openssl.cnf \
    "$r"/etc/perl "$r"/etc/debconf.conf
  cat >"$r/etc/passwd" <<'EOF'
root:x:0:0:root:/root:/sbin/nologin
nobody:x:65534:65534:nobody:/nonexistent:/sbin/nologin
nonroot:x:65532:65532:nonroot:/home/nonroot:/sbin/nologin
EOF
  cat >"$r/etc/group" <<'EOF'
root:x:0:
tty:x:5:
staff:x:50:
nogroup:x:65534:
nonroot:x:65532:
EOF
  printf 'passwd: files\ngroup: files\nhosts: files dns\n' >"$r/etc/nsswitch.conf"
  install -d -m 700 -o 65532 -g 65532 "$r/home/nonroot"
  install -d -m 700 "$r/root"
  install -d -m 1777 "$r/tmp"
}

case "${1:-}" in
  hook-builder) hook_builder "$2"; exit ;;
  hook-runtime) hook_runtime "$2"; exit ;;
  "") ;;
  *) die "usage: $0 (no arguments)" ;;
esac

# ---------------------------------------------------------------------------------------
[ "$(id -u)" = 0 ] || die "run as root (podman build, chroot and mounts)"

START=$SECONDS
declare -a SUMMARY=()
step_start=0
step() { step_start=$SECONDS; say "$1 (at $((SECONDS - START)) s)"; }
done_step() { SUMMARY+=("$(printf '%-44s %4d s' "$1" $((SECONDS - step_start)))"); }
note() { SUMMARY+=("$1"); }

WORK=$(mktemp -d "${TMPDIR:-/tmp}/reflectance-container.XXXXXX")
SERVER_PID=""
CONTAINER=""
cleanup() {
  local rc=$?
  if [ -n "$SERVER_PID" ] && kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -TERM "$SERVER_PID" 2>/dev/null || true
    sleep 1
    kill -KILL "$SERVER_PID" 2>/dev/null || true
  fi
  [ -z "$CONTAINER" ] || podman rm -f "$CONTAINER" >/dev/null 2>&1 || true
  # The mounts of each run live in its own mount namespace and went with it; the exported
  # root filesystem is plain files.
  rm -rf "$WORK"
  if [ "$rc" != 0 ]; then echo "container check: FAILED (exit $rc)" >&2; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---------------------------------------------------------------------------------------
step "tools (podman, mmdebstrap, jq, curl)"
missing=()
command -v podman >/dev/null || missing+=(podman)
command -v mmdebstrap >/dev/null || missing+=(mmdebstrap)
command -v jq >/dev/null || missing+=(jq)
command -v curl >/dev/null || missing+=(curl)
command -v unshare >/dev/null || missing+=(util-linux)
command -v python3 >/dev/null || missing+=(python3)
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing ${missing[*]}"
  apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >"$WORK/apt.log" 2>&1 \
    || { tail -20 "$WORK/apt.log"; die "apt-get install ${missing[*]} failed"; }
fi
podman --version
done_step "tools${missing:+ (installed ${missing[*]})}"

# ---------------------------------------------------------------------------------------
# The base images the Dockerfile names, as the registry would resolve them.
qualify() {
  local ref=$1 first=${1%%/*}
  if [[ $ref != */* ]]; then
    echo "docker.io/library/$ref"
  elif [[ $first == *.* || $first == *:* || $first == localhost ]]; then
    echo "$ref"
  else
    echo "docker.io/$ref"
  fi
}
RUST_VERSION=$(sed -n 's/^ARG RUST_VERSION=//p' Dockerfile | head -1)
[ -n "$RUST_VERSION" ] || die "the Dockerfile has no ARG RUST_VERSION=… default"
froms=$(awk 'toupper($1) == "FROM" {print $2}' Dockerfile | sed "s/\${RUST_VERSION}/$RUST_VERSION/g")
BUILDER_BASE=$(qualify "$(grep -m1 '^rust:' <<<"$froms")") || die "no FROM rust:… in the Dockerfile"
RUNTIME_BASE=$(qualify "$(grep -m1 'distroless' <<<"$froms")") || die "no distroless FROM in the Dockerfile"

# The host's toolchain of that version (rustup), as the rust image would hold it.
host_rustc() { rustc "+$RUST_VERSION" "$@" 2>/dev/null || rustc "$@"; }
RUSTC_VERSION=$(host_rustc --version | awk '{print $2}')
case "$RUSTC_VERSION" in
  "$RUST_VERSION" | "$RUST_VERSION".*) ;;
  *) die "the Dockerfile builds with Rust $RUST_VERSION, this machine has rustc $RUSTC_VERSION (rustup toolchain install $RUST_VERSION)" ;;
esac
export STANDIN_SYSROOT STANDIN_TOOLCHAIN STANDIN_RUSTUP
STANDIN_SYSROOT=$(readlink -f "$(host_rustc --print sysroot)")
STANDIN_TOOLCHAIN="$RUSTC_VERSION-$(host_rustc -vV | sed -n 's/^host: //p')"
STANDIN_RUSTUP=$(readlink -f "$(command -v rustup)") || die "rustup is needed (the rust image's layout)"
[ -x "$STANDIN_SYSROOT/bin/cargo" ] || die "no cargo in $STANDIN_SYSROOT"

# What each stand-in was built from, by image id, kept beside the cache (not as a label,
# which the built image would inherit).
fingerprint_file() { echo "$CACHE/standin-$(tr -c 'a-zA-Z0-9.\n-' _ <<<"$1")"; }
base_is_current() {  # image, fingerprint
  [ -z "${REFLECTANCE_CONTAINER_REBUILD_BASES:-}" ] && podman image exists "$1" \
    && [ "$(cat "$(fingerprint_file "$1")" 2>/dev/null)" = "$(podman image inspect --format '{{.Id}}' "$1") $2" ]
}
remember_base() {  # image, fingerprint
  echo "$(podman image inspect --format '{{.Id}}' "$1") $2" >"$(fingerprint_file "$1")"
}
SOURCES=("deb $MIRROR bookworm main" "deb $MIRROR bookworm-updates main"
  "deb $SECURITY_MIRROR bookworm-security main")
# debian:bookworm-slim's dpkg exclusions (the rust slim image's base).
SLIM=(--dpkgopt='path-exclude=/usr/share/doc/*' --dpkgopt='path-include=/usr/share/doc/*/copyright'
  --dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/info/*'
  --dpkgopt='path-exclude=/usr/share/locale/*' --dpkgopt='path-include=/usr/share/locale/locale.alias'
  --dpkgopt='path-exclude=/usr/share/lintian/*')

build_builder_base() {
  local fp="rust $RUSTC_VERSION, rustup $("$STANDIN_RUSTUP" --version 2>/dev/null | awk '{print $2}'), recipe $RECIPE"
  if base_is_current "$BUILDER_BASE" "$fp"; then
    echo "$BUILDER_BASE: kept ($fp)"
    return
  fi
  mmdebstrap --variant=minbase --include=ca-certificates,gcc,libc6-dev,cmake,make,nasm "${SLIM[@]}" \
      --customize-hook="bash '$SELF' hook-builder \"\$1\"" bookworm - "${SOURCES[@]}" </dev/null \
    | podman import -q \
      --change "ENV PATH=/usr/local/cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin" \
      --change "ENV RUSTUP_HOME=/usr/local/rustup" --change "ENV CARGO_HOME=/usr/local/cargo" \
      --change "ENV RUST_VERSION=$RUSTC_VERSION" --change 'CMD ["bash"]' \
      - "$BUILDER_BASE" >/dev/null
  remember_base "$BUILDER_BASE" "$fp"
  echo "$BUILDER_BASE: built ($fp)"
}
build_runtime_base() {
  local fp="bookworm, recipe $RECIPE"
  if base_is_current "$RUNTIME_BASE" "$fp"; then
    echo "$RUNTIME_BASE: kept ($fp)"
    return
  fi
  mmdebstrap --variant=extract \
      --include=base-files,netbase,tzdata,ca-certificates,libc6,libgcc-s1,libgomp1,libstdc++6,libssl3 \
      --extract-hook="bash '$SELF' hook-runtime \"\$1\"" bookworm - "${SOURCES[@]}" </dev/null \
    | podman import -q \
      --change "ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin" \
      --change "ENV SSL_CERT_FILE=/etc/ssl/certs/ca-certificates.crt" \
      --change "USER 65532" --change "WORKDIR /home/nonroot" \
      - "$RUNTIME_BASE" >/dev/null
  remember_base "$RUNTIME_BASE" "$fp"
  echo "$RUNTIME_BASE: built ($fp)"
}

step "base images: stand-ins of $BUILDER_BASE and $RUNTIME_BASE"
mkdir -p "$CACHE"
# Both at once (mostly downloads and unpacking).
build_builder_base >"$WORK/builder-base.log" 2>&1 &
builder_job=$!
build_runtime_base >"$WORK/runtime-base.log" 2>&1 &
runtime_job=$!
wait "$builder_job" || { tail -30 "$WORK/builder-base.log"; die "the builder's stand-in failed"; }
wait "$runtime_job" || { tail -30 "$WORK/runtime-base.log"; die "the runtime's stand-in failed"; }
tail -1 "$WORK/builder-base.log"
tail -1 "$WORK/runtime-base.log"
done_step "base images ($(tail -1 "$WORK/builder-base.log" | grep -o 'kept\|built'), $(tail -1 "$WORK/runtime-base.log" | grep -o 'kept\|built'))"

# ---------------------------------------------------------------------------------------
step "image: podman build of the Dockerfile as it is, tagged $TAG"
# The build downloads its crates itself (no registry shared with this machine: all 294 of
# the workspace take about 6 s, not worth a difference from a real build).
build_args=(--isolation=chroot --pull=never --format docker --layers -t "$TAG" -f Dockerfile)
# The machine's certificate authorities, for the build's downloads (crates.io): where egress
# goes through a proxy that re-signs TLS, as here, the rust image's own bundle would refuse
# it. Mounted for the build only, so the images hold nothing of this machine.
if [ -f /etc/ssl/certs/ca-certificates.crt ]; then
  build_args+=(--volume /etc/ssl/certs/ca-certificates.crt:/etc/ssl/certs/ca-certificates.crt:ro)
fi
[ -z "${REFLECTANCE_CONTAINER_NO_CACHE:-}" ] || build_args+=(--no-cache)
mkdir -p "$CACHE"
BUILD_LOG="$CACHE/build.log"
if ! podman build "${build_args[@]}" . >"$BUILD_LOG" 2>&1; then
  tail -60 "$BUILD_LOG"
  die "podman build failed (its log: $BUILD_LOG)"
fi
# The steps, what came from the cache, cargo's times; the whole log stays in $BUILD_LOG.
grep -E 'STEP [0-9]+/[0-9]+: [A-Z]+ |--> Using cache|Finished|Installed package|level=warn|warning:' "$BUILD_LOG" \
  | cut -c1-150 || true
# Cache images of earlier builds that this build did not use (each build of changed sources
# leaves its compiled target/ behind, about a gigabyte): the untagged images descending from
# the two stand-ins, but for the steps of this build and their parents; children first.
stale_layers() {
  podman image inspect --format '{{.Id}} {{.Parent}}- {{len .RepoTags}}' \
    $(podman images -a -q --no-trunc) >"$WORK/images"
  python3 - "$WORK/images" "$BUILD_LOG" "$(podman image inspect --format '{{.Id}}' "$BUILDER_BASE")" \
      "$(podman image inspect --format '{{.Id}}' "$RUNTIME_BASE")" <<'PY'
import re, sys
images, log, *bases = sys.argv[1:]
parent, tagged = {}, set()
for line in open(images):
    i, p, tags = line.split()
    parent[i] = p.rstrip("-")
    if tags != "0":
        tagged.add(i)
used = re.findall(r"--> (?:Using cache )?([0-9a-f]{11,64})\b", open(log).read())
keep = {i for i in parent if i in tagged or any(i.startswith(u) for u in used)}
for i in list(keep):  # and their ancestors
    while parent.get(i):
        i = parent[i]
        keep.add(i)
def depth(i):
    d = 0
    while i and i not in bases:
        i, d = parent.get(i), d + 1
    return d if i in bases else 0
for _, i in sorted(((depth(i), i) for i in parent if i not in keep and depth(i)), reverse=True):
    print(i)
PY
}
for id in $(stale_layers); do
  podman rmi "$id" >/dev/null 2>&1 || true
done
cached=$(grep -c -- '--> Using cache' "$BUILD_LOG" || true)
done_step "image build ($cached steps from cache)"
# cargo's own times, by step.
awk '/STEP [0-9]+\/[0-9]+: RUN cargo/ {sub(/.*RUN /, ""); sub(/ +&&.*/, ""); step = $0}
     /Finished `release`/ && step {sub(/.* in /, ""); sub(/ --.*/, "", step); printf "  %-42s %s\n", step, $0; step = ""}' \
  "$BUILD_LOG" >"$WORK/cargo-times"
while IFS= read -r line; do note "$line"; done <"$WORK/cargo-times"

# ---------------------------------------------------------------------------------------
step "image configuration"
problems=0
fail() { echo "FAIL: $*"; problems=$((problems + 1)); }
pass() { echo "ok:   $*"; }
podman image inspect "$TAG" >"$WORK/inspect.json"
cfg() { jq -c "$1" "$WORK/inspect.json"; }
env_of() { jq -r --arg k "$1" '.[0].Config.Env[] | select(startswith($k + "=")) | sub("^[^=]*="; "")' "$WORK/inspect.json"; }

# The root filesystem, for the checks below and the run.
R="$WORK/rootfs"
mkdir -p "$R"
# (podman create says it cannot reach systemd for the health check's timer: no matter here.)
CONTAINER=$(podman create "$TAG" 2>"$WORK/create.log") || { cat "$WORK/create.log"; die "podman create failed"; }
podman export "$CONTAINER" | tar -C "$R" --numeric-owner -xpf -
podman rm "$CONTAINER" >/dev/null 2>>"$WORK/create.log"
CONTAINER=""

user=$(jq -r '.[0].Config.User' "$WORK/inspect.json")
uid=${user%%:*} gid=${user#*:}
[ "$gid" != "$user" ] || gid=""
[[ $uid =~ ^[0-9]+$ ]] || uid=$(awk -F: -v n="$uid" '$1 == n {print $3}' "$R/etc/passwd")
[ -n "$gid" ] || gid=$(awk -F: -v n="$uid" '$3 == n {print $4}' "$R/etc/passwd")
[[ $gid =~ ^[0-9]+$ ]] || gid=$(awk -F: -v n="$gid" '$1 == n {print $3}' "$R/etc/group")
if [ "$uid" = 65532 ] && [ "$gid" = 65532 ]; then pass "user $user = $uid:$gid"; else fail "user $user = ${uid:-?}:${gid:-?}, not 65532:65532"; fi
home=$(awk -F: -v n="$uid" '$3 == n {print $6}' "$R/etc/passwd")

listen=$(env_of REFLECTANCE_LISTEN)
port=${listen##*:}
exposed=$(cfg '.[0].Config.ExposedPorts | keys')
if [ "$exposed" = "[\"$port/tcp\"]" ]; then pass "exposes $exposed, the port of REFLECTANCE_LISTEN=$listen"; else fail "exposes $exposed, REFLECTANCE_LISTEN=$listen"; fi

entrypoint=$(cfg '.[0].Config.Entrypoint')
cmd=$(cfg '.[0].Config.Cmd')
binary=$(jq -r '.[0].Config.Entrypoint[0]' "$WORK/inspect.json")
if [ -x "$R$binary" ] && [ "$cmd" = '["serve"]' ]; then pass "entrypoint $entrypoint, command $cmd"; else fail "entrypoint $entrypoint (executable in the image?), command $cmd"; fi

health=$(cfg '.[0].Healthcheck // .[0].HealthCheck // .[0].Config.Healthcheck')
if [ "$(jq -c '.Test' <<<"$health")" = "[\"CMD\",\"$binary\",\"healthcheck\"]" ]; then
  pass "health check $(jq -c '{Test, Interval: (.Interval / 1e9), Timeout: (.Timeout / 1e9), StartPeriod: (.StartPeriod / 1e9), Retries}' <<<"$health")"
else
  fail "health check: $health"
fi

models=$(env_of REFLECTANCE_MODELS)
default_model=$(env_of REFLECTANCE_DEFAULT_MODEL)
in_image=$(cd "$R$models" && find . -type f | sed 's|^\./||' | sort)
# Each model's latest version: the one served, the only one the image holds.
latest_files() {
  sed 's|^models/||' | awk -F/ 'NF >= 3 && $2 ~ /^[0-9]+$/ { v[$1] = ($2 > v[$1] ? $2 : v[$1]); f[NR] = $0; m[NR] = $1; n[NR] = $2 }
    END { for (i in f) if (n[i] == v[m[i]]) print f[i] }' | sort
}
tracked=$(git ls-files models 2>/dev/null | latest_files || true)
[ -n "$tracked" ] || tracked=$(find models -type f | latest_files)
if [ "$in_image" = "$tracked" ] && (cd models && sha256sum --quiet -c <(cd "$R$models" && sha256sum $in_image)); then
  pass "models in $models: $(echo $in_image) (the shipped ones, byte for byte)"
else
  fail "models in $models: $(echo $in_image); shipped: $(echo $tracked)"
fi
[ -n "$(find "$R$models/$default_model" -name model.json 2>/dev/null)" ] || fail "the default model $default_model is not in the image"

data=$(env_of REFLECTANCE_DATA_DIR)
if [ "$(stat -c '%u:%g' "$R$data" 2>/dev/null)" = "$uid:$gid" ] && [ -z "$(ls -A "$R$data")" ]; then
  pass "data directory $data: empty, owned by $uid:$gid"
else
  fail "data directory $data: $(stat -c '%U:%G %u:%g' "$R$data" 2>&1), $(ls -A "$R$data" 2>&1 | head -3)"
fi
if [ -e "$R/bin/sh" ] || [ -e "$R/usr/bin/sh" ]; then fail "the image has a shell"; else pass "no shell"; fi

size=$(jq -r '.[0].Size' "$WORK/inspect.json")
base_size=$(podman image inspect --format '{{.Size}}' "$RUNTIME_BASE")
bin_size=$(stat -c %s "$R$binary")
mb() { awk -v b="$1" 'BEGIN {printf "%.1f MB", b / 1e6}'; }
if [ "$size" -le 60000000 ]; then pass "size $(mb "$size") (≤ 60 MB)"; else fail "size $(mb "$size") (> 60 MB)"; fi
echo "      base $(mb "$base_size"), binary $(mb "$bin_size"), models $(mb "$(du -sb "$R$models" | cut -f1)")"
note "$(printf '%-44s %s' "runtime image size" "$(mb "$size") (base $(mb "$base_size"), binary $(mb "$bin_size"))")"

# ---------------------------------------------------------------------------------------
step "the entrypoint, run from the image's root filesystem as $uid:$gid"
# The image's environment, working directory and HOME (a runtime sets HOME from passwd).
jq -r '.[0].Config.Env[]' "$WORK/inspect.json" >"$WORK/env"
grep -q '^HOME=' "$WORK/env" || echo "HOME=${home:-/}" >>"$WORK/env"
workdir=$(jq -r '.[0].Config.WorkingDir // "/"' "$WORK/inspect.json")
[ -n "$workdir" ] || workdir=/

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
PORT=$(free_port)
ADMIN_PORT=$(free_port)
while [ "$ADMIN_PORT" = "$PORT" ]; do ADMIN_PORT=$(free_port); done
TOKEN=$(head -c 24 /dev/urandom | base64)

# In a private mount namespace (its mounts go with its last process): /proc and a minimal
# /dev, as a container runtime gives; then chroot, the working directory, no supplementary
# groups, gid, uid (no capabilities left), and exec with exactly the given environment.
LAUNCH='
import json, os, sys
root, workdir, uid, gid, envfile = sys.argv[1:6]
argv = sys.argv[6:]
env = dict(l.split("=", 1) for l in open(envfile).read().splitlines() if "=" in l)
os.chroot(root)
os.chdir(workdir)
os.setgroups([])
os.setgid(int(gid))
os.setuid(int(uid))
os.execve(argv[0], argv, env)
'
run_in_image() {  # envfile, argv…; replaces the calling (sub)shell, whose pid the server keeps
  local envfile=$1
  shift
  exec unshare --mount --propagation private -- bash -c '
    set -e
    r=$1
    mount -t proc -o nosuid,nodev,noexec proc "$r/proc"
    mount -t tmpfs -o nosuid,mode=755,size=64k dev "$r/dev"
    mknod -m 666 "$r/dev/null" c 1 3; mknod -m 666 "$r/dev/zero" c 1 5; mknod -m 666 "$r/dev/full" c 1 7
    mknod -m 666 "$r/dev/random" c 1 8; mknod -m 666 "$r/dev/urandom" c 1 9
    ln -s /proc/self/fd "$r/dev/fd"
    shift
    exec python3 -c "$@"
  ' _ "$R" "$LAUNCH" "$R" "$workdir" "$uid" "$gid" "$envfile" "$@"
}
snapshot() {  # every path of the root filesystem but the data directory, with its metadata
  (cd "$R" && find . -path "./${data#/}" -prune -o -printf '%y %m %u:%g %s %T@ %p %l\n' | sort)
}

# The files the operator puts on the data volume for the job: a small synthetic light probe
# (a flat Radiance RGBE file) and a class file of two materials.
install -d -o "$uid" -g "$gid" "$R$data/probes"
python3 - "$R$data/probes/sky.hdr" <<'EOF'
import math, sys
w, h = 64, 32
out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
for y in range(h):
    for x in range(w):
        v = 0.2 + 3 * max(0.0, math.cos(6.283 * x / w)) * (1 - y / h)
        e = math.frexp(v)[1]
        m = int(v * 256.0 / 2.0**e)
        out += bytes([m, m, m, e + 128])
open(sys.argv[1], "wb").write(out)
EOF
cat >"$R$data/classes.json" <<'EOF'
{"classes": [
  {"name": "matte", "rho_d": 0.6, "rho_s": 0.0, "alpha": 0.0},
  {"name": "shiny", "rho_d": 0.1, "rho_s": 0.3, "alpha": 0.05}
]}
EOF
chown -R "$uid:$gid" "$R$data"
snapshot >"$WORK/before"

# The image's health check with no server: must fail.
cp "$WORK/env" "$WORK/env.serve"
sed -i "s|^REFLECTANCE_LISTEN=.*|REFLECTANCE_LISTEN=${listen%:*}:$PORT|" "$WORK/env.serve"
mapfile -t health_cmd < <(jq -r '.Test[1:][]' <<<"$health")
if (run_in_image "$WORK/env.serve" "${health_cmd[@]}") >"$WORK/health0.log" 2>&1; then
  fail "the health check passed with no server"
else
  pass "the health check fails with no server ($(head -c 120 "$WORK/health0.log" | tr '\n' ' '))"
fi

# serve, with the admin plane on (a token in the environment, loopback).
cp "$WORK/env.serve" "$WORK/env.admin"
printf 'REFLECTANCE_ADMIN_TOKEN=%s\nREFLECTANCE_ADMIN_LISTEN=127.0.0.1:%s\n' "$TOKEN" "$ADMIN_PORT" >>"$WORK/env.admin"
mapfile -t serve_cmd < <(jq -r '.[0].Config.Entrypoint[], .[0].Config.Cmd[]' "$WORK/inspect.json")
run_in_image "$WORK/env.admin" "${serve_cmd[@]}" >"$WORK/serve.log" 2>&1 &
SERVER_PID=$!
ready=""
for _ in $(seq 1 150); do
  if (run_in_image "$WORK/env.serve" "${health_cmd[@]}") >/dev/null 2>&1; then ready=1; break; fi
  kill -0 "$SERVER_PID" 2>/dev/null || break
  sleep 0.2
done
if [ -n "$ready" ]; then
  pass "serve started; the image's health check passes (REFLECTANCE_LISTEN=${listen%:*}:$PORT)"
else
  tail -20 "$WORK/serve.log"
  die "serve did not become ready"
fi
status=$(grep -E '^(Uid|Gid|Groups|CapEff|CapPrm):' "/proc/$SERVER_PID/status" | tr -s '\t ' ' ' | tr '\n' ';')
if [[ $status == "Uid: $uid $uid $uid $uid;Gid: $gid $gid $gid $gid;Groups: ;"* ]] && [[ $status == *"CapPrm: 0000000000000000;CapEff: 0000000000000000;"* ]]; then
  pass "the server runs as uid $uid, gid $gid, no groups, no capabilities (/proc/$SERVER_PID/status)"
else
  fail "the server's credentials: $status"
fi
[ "$(readlink "/proc/$SERVER_PID/root")" = "$R" ] || fail "the server's root is $(readlink "/proc/$SERVER_PID/root"), not the image's"

answer=$(curl -s --max-time 30 -F "image=@$FIXTURE" -F white=0.8 -F cx=96.5 -F cy=94.25 -F r=85 \
  "http://127.0.0.1:$PORT/v1/classify" || true)
label=$(jq -r '.label // empty' <<<"$answer" 2>/dev/null || true)
if [ "$label" = chrome ]; then
  pass "POST /v1/classify $FIXTURE: $(jq -c '{label: .label, model: .model}' <<<"$answer")"
else
  fail "POST /v1/classify $FIXTURE: ${answer:0:300}"
fi

# An admin job that writes into the data directory: a render of the probe × 2 classes.
H="Authorization: Bearer $TOKEN"
unauthorized=$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs")
[ "$unauthorized" = 401 ] || fail "the admin plane without a token answered $unauthorized, not 401"
job=$(curl -s --max-time 30 -H "$H" -H 'content-type: application/json' "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs" \
  -d '{"type": "render", "probes": "probes", "classes": "classes.json", "out": "renders/check", "size": 72, "seed": 1}' || true)
id=$(jq -r '.id // empty' <<<"$job" 2>/dev/null || true)
record=""
if [ -n "$id" ]; then
  for _ in $(seq 1 300); do
    record=$(curl -s -H "$H" "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs/$id" || true)
    state=$(jq -r '.state' <<<"$record" 2>/dev/null || true)
    [ "$state" = queued ] || [ "$state" = running ] || break
    sleep 0.2
  done
fi
written=$(cd "$R$data" && find . -newer "$WORK/before" \( -type f -o -type d \) -printf '%u:%g %p\n' | sort)
owners=$(awk '{print $1}' <<<"$written" | sort -u | tr '\n' ' ')
images=$(find "$R$data/renders/check" -name '*.pfm' 2>/dev/null | wc -l)
if [ "$(jq -r '.state' <<<"$record" 2>/dev/null)" = succeeded ] && [ "$images" = 2 ] \
    && [ -f "$R$data/renders/check/manifest.csv" ] && [ -f "$R$data/jobs/$id.json" ] && [ "$owners" = "$uid:$gid " ]; then
  pass "admin render job $id: $(jq -c '{state, result}' <<<"$record"); $(wc -l <<<"$written") paths written under $data, owned by $uid:$gid"
else
  fail "admin render job: ${record:-$job}; $images images; written under $data: $(head -c 400 <<<"$written")"
fi

# SIGTERM: the server drains and exits 0.
kill -TERM "$SERVER_PID"
stopped=""
for _ in $(seq 1 300); do
  kill -0 "$SERVER_PID" 2>/dev/null || { stopped=1; break; }
  sleep 0.1
done
if [ -n "$stopped" ] && wait "$SERVER_PID"; then
  pass "serve stopped on SIGTERM, exit 0"
else
  fail "serve did not stop cleanly on SIGTERM"
fi
SERVER_PID=""
# Warnings or errors, but for the readiness answers 503 while the models loaded (the server
# logs every 5xx at warn).
grep -E '"level":"(ERROR|WARN)"' "$WORK/serve.log" \
  | grep -vE '"path":"/health/ready","status":503' >"$WORK/warnings" || true
if [ -s "$WORK/warnings" ]; then
  fail "the server logged warnings or errors:"
  head -5 "$WORK/warnings"
fi

snapshot >"$WORK/after"
if diff "$WORK/before" "$WORK/after" >"$WORK/diff"; then
  pass "nothing written outside $data ($(wc -l <"$WORK/after") paths compared)"
else
  fail "files changed outside $data:"
  head -20 "$WORK/diff"
fi
done_step "run (health check, classify, admin job)"

echo
echo "container check: $TAG ($(jq -r '.[0].Id[:12]' "$WORK/inspect.json")), in $((SECONDS - START)) s"
printf '  %s\n' "${SUMMARY[@]}"
if [ "$problems" -gt 0 ]; then
  die "$problems problem(s) (see FAIL above)"
fi
echo "container check: ok"
