#!/usr/bin/env bash
# Build the service image with podman and try it for real (`make test-container`).
#
#   1. a local base image, localhost/efdm-base:bookworm (Debian bookworm minbase + python3.11
#      and venv), made with debootstrap because no container registry is reachable; its root
#      file system is cached as a tarball, so later runs only import it (or reuse the image);
#   2. podman build of docker/Dockerfile on that base (pip reaches PyPI with the host's CA
#      bundle, passed as a build secret);
#   3. the container on a free 127.0.0.1 port: tests/deploy/container_smoke.py (a session,
#      3 JPEG frames over REST, one over the WebSocket, /readyz, /metrics, the demo page), the
#      image's HEALTHCHECK, non-root user, no dev packages, then a graceful stop (exit 0);
#   4. docker/compose.yaml's topology with podman: Redis, the replicas and nginx with
#      docker/nginx.conf; the smoke test through nginx (shared sessions, affinity by session),
#      and /readyz going 503 when Redis stops (SKIP_TOPOLOGY=1 skips this part).
#
# Needs root, podman (runc) and debootstrap:
#   apt-get install -y podman runc buildah fuse-overlayfs uidmap debootstrap
#
# Environment: PYTHON (default .venv/bin/python), CONTAINER_CACHE_DIR (default
# ~/.cache/efdm-container), IMAGE (default localhost/efdm-tracker:test), DEBIAN_MIRROR (default
# http://deb.debian.org/debian), PIP_CERT (CA bundle for pip in the build; default the
# system's), SKIP_TOPOLOGY=1.
#
# Images: the base, the stand-in infra image, IMAGE and the dependency stages (tagged
# $DEPS_IMAGE, so that reruns reuse podman's layer cache and pip runs only when the
# dependencies change) are kept. Every build on a changed source leaves the previous image and
# its stages untagged: they are removed after the build (only dangling images made on this
# script's base, never other images of the host), or the disk fills within a few dozen runs.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
cd "$root"

export CONTAINERS_CONF="${CONTAINERS_CONF:-$here/containers.conf}"
PYTHON=${PYTHON:-$root/.venv/bin/python}
IMAGE=${IMAGE:-localhost/efdm-tracker:test}
BASE_IMAGE=localhost/efdm-base:bookworm
DEPS_IMAGE=localhost/efdm-tracker:deps-cache
MIN_FREE_GIB=4  # a build that reinstalls the dependencies writes about 2 GiB of layers
BASE_RECIPE=1  # bump when the base recipe below changes: the cached tarball is then rebuilt
CACHE_DIR=${CONTAINER_CACHE_DIR:-${XDG_CACHE_HOME:-${HOME:-/root}/.cache}/efdm-container}
BASE_TAR=$CACHE_DIR/bookworm-python3-r$BASE_RECIPE.tar.gz
DEBIAN_MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}

started=$(date +%s)
step() { printf '== [%3ss] %s\n' "$(($(date +%s) - started))" "$*"; }
die() { echo "test-container: error: $*" >&2; exit 1; }

containers=()  # everything this run started, removed on exit
network=""
workdir=""
cleanup() {
  local status=$?
  local c
  for c in "${containers[@]}"; do
    if [ "$status" -ne 0 ]; then
      echo "---- logs of $c (last 40 lines) ----" >&2
      podman logs --tail 40 "$c" >&2 || true
    fi
    podman rm --force --time 0 "$c" >/dev/null 2>&1 || true
  done
  if [ -n "$network" ]; then
    podman network rm --force "$network" >/dev/null 2>&1 || true
  fi
  if [ -n "$workdir" ]; then
    # a failed debootstrap can leave a mount behind: never delete through it
    umount --recursive "$workdir/rootfs/proc" 2>/dev/null || true
    rm -rf --one-file-system "$workdir"
  fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

command -v podman >/dev/null || die "podman is not installed (apt-get install podman runc buildah fuse-overlayfs uidmap debootstrap)"
[ -x "$PYTHON" ] || die "$PYTHON not found: run 'make venv' first, or set PYTHON"

# ---------------------------------------------------------------- 1. base image
make_base_tarball() {
  command -v debootstrap >/dev/null || die "debootstrap is not installed"
  [ "$(id -u)" -eq 0 ] || die "making the base image needs root (debootstrap, chroot)"
  workdir=$(mktemp -d "${TMPDIR:-/var/tmp}/efdm-base.XXXXXX")
  local rootfs=$workdir/rootfs
  step "debootstrap --variant=minbase bookworm ($DEBIAN_MIRROR)"
  debootstrap --variant=minbase bookworm "$rootfs" "$DEBIAN_MIRROR" >"$workdir/debootstrap.log" 2>&1 \
    || { tail -30 "$workdir/debootstrap.log" >&2; die "debootstrap failed"; }
  step "python3 python3-venv python3-pip into the base (chroot apt-get)"
  cp /etc/resolv.conf "$rootfs/etc/resolv.conf"
  mount -t proc proc "$rootfs/proc"
  chroot "$rootfs" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
    sh -euc 'apt-get update -qq
             apt-get install -y -qq --no-install-recommends python3 python3-venv python3-pip >/dev/null
             apt-get clean
             rm -rf /var/lib/apt/lists/* /var/cache/apt/*.bin /var/log/apt /var/log/dpkg.log'
  umount "$rootfs/proc"
  : >"$rootfs/etc/resolv.conf"
  rm -f "$rootfs/etc/hostname"
  chroot "$rootfs" python3 -c 'import ensurepip, sys, venv; assert sys.version_info >= (3, 11)' \
    || die "python3 (>= 3.11, with venv) missing from the base"
  mkdir -p "$CACHE_DIR"
  step "caching the base root file system: $BASE_TAR"
  tar --numeric-owner -C "$rootfs" -c . | gzip -1 >"$BASE_TAR.tmp"
  mv "$BASE_TAR.tmp" "$BASE_TAR"
  rm -rf --one-file-system "$workdir"
  workdir=""
}

if podman image exists "$BASE_IMAGE" \
  && [ "$(podman image inspect --format '{{index .Labels "efdm.base.recipe"}}' "$BASE_IMAGE" 2>/dev/null)" = "$BASE_RECIPE" ]; then
  step "base image $BASE_IMAGE present"
else
  [ -s "$BASE_TAR" ] || make_base_tarball
  step "podman import $BASE_TAR -> $BASE_IMAGE"
  podman import --quiet \
    --change 'ENV LANG=C.UTF-8' \
    --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
    --change "LABEL efdm.base.recipe=$BASE_RECIPE" \
    --change 'CMD ["/bin/bash"]' \
    "$BASE_TAR" "$BASE_IMAGE" >/dev/null
fi

# ---------------------------------------------------------------- 2. build
store=$(podman info --format '{{.Store.GraphRoot}}')
free_kib=$(df --output=avail -k "$store" | tail -1)
[ "$free_kib" -ge $((MIN_FREE_GIB * 1024 * 1024)) ] \
  || die "only $((free_kib / 1024)) MiB free under $store: a build needs $MIN_FREE_GIB GiB"
build_args=(--format docker --file docker/Dockerfile --build-arg "BASE_IMAGE=$BASE_IMAGE")
cert=${PIP_CERT:-/etc/ssl/certs/ca-certificates.crt}
if [ -s "$cert" ]; then
  build_args+=(--secret "id=pip_cert,src=$cert")
fi
step "podman build ${build_args[*]} --tag $IMAGE ."
podman build --quiet "${build_args[@]}" --target venv --tag "$DEPS_IMAGE" . >/dev/null
podman build --quiet "${build_args[@]}" --tag "$IMAGE" . >/dev/null
podman images --format '   {{.Repository}}:{{.Tag}} {{.ID}} {{.Size}}' "$IMAGE"
# what earlier builds left untagged; the label comes from the base, so other images are spared
removed=$(podman image prune --force --filter label=efdm.base.recipe | wc -l)
step "removed $removed dangling images of earlier builds"


# ---------------------------------------------------------------- 3. one container
free_port() {
  "$PYTHON" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# wait_http URL CONTAINER: until URL answers 200, failing early if CONTAINER exits
wait_http() {
  local url=$1 c=$2 deadline=$(($(date +%s) + 180))
  until "$PYTHON" -c "import urllib.request as u; u.urlopen('$url', timeout=2)" 2>/dev/null; do
    [ "$(podman inspect --format '{{.State.Running}}' "$c")" = true ] \
      || die "$c exited ($(podman inspect --format '{{.State.ExitCode}}' "$c"))"
    [ "$(date +%s)" -lt "$deadline" ] || die "$url did not answer within 180 s"
    sleep 0.5
  done
}

port=$(free_port)
container=efdm-test-$$
step "podman run -p 127.0.0.1:$port:8000 $IMAGE"
# --no-healthcheck: podman would need systemd timers for it; the image's HEALTHCHECK command
# is run once by hand below instead
containers+=("$container")
podman run --detach --name "$container" --publish "127.0.0.1:$port:8000" --no-healthcheck \
  "$IMAGE" >/dev/null
wait_http "http://127.0.0.1:$port/healthz" "$container"

step "smoke test: tests/deploy/container_smoke.py http://127.0.0.1:$port"
"$PYTHON" -m tests.deploy.container_smoke "http://127.0.0.1:$port"

step "image checks: HEALTHCHECK, user, no dev packages, writable numba cache"
# the HEALTHCHECK exactly as the image declares it (["CMD", argv...])
mapfile -t health < <(podman image inspect --format '{{json .Config.Healthcheck.Test}}' "$IMAGE" \
  | "$PYTHON" -c 'import json, sys; t = json.load(sys.stdin); assert t[0] == "CMD", t; print("\n".join(t[1:]))')
[ "${#health[@]}" -gt 0 ] || die "the image declares no HEALTHCHECK (build with --format docker)"
podman exec "$container" "${health[@]}" || die "the image's HEALTHCHECK failed"
[ "$(podman exec "$container" id -u)" = 10001 ] || die "the service does not run as uid 10001"
podman exec "$container" python -c '
import importlib.util, os
dev = [m for m in ("pytest", "mypy", "ruff", "hypothesis", "pip", "setuptools") if importlib.util.find_spec(m)]
assert not dev, f"not runtime dependencies: {dev}"
cache = os.environ["NUMBA_CACHE_DIR"]
assert os.access(cache, os.W_OK) and os.listdir(cache), f"numba cache {cache} not written"
pid1 = open("/proc/1/cmdline", "rb").read().split(b"\0")
assert b"efdm" in pid1[1] and pid1[2] == b"serve", f"PID 1 is {pid1}"
' || die "image checks failed"

step "graceful stop (SIGTERM to PID 1)"
podman stop --time 20 "$container" >/dev/null
code=$(podman inspect --format '{{.State.ExitCode}}' "$container")
[ "$code" = 0 ] || die "the service exited with $code on SIGTERM"
podman rm "$container" >/dev/null

# ---------------------------------------------------------------- 4. compose's topology
# docker/compose.yaml as podman containers: Redis, the replicas (their environment, read-only
# root and tmpfs read from compose.yaml) and nginx with docker/nginx.conf, on one network.
# The official redis and nginx images cannot be pulled here: Debian's redis-server and nginx
# on the same base stand in for them. Not checked: compose's own semantics (depends_on,
# healthcheck timers, restart policies), which need docker compose.
if [ "${SKIP_TOPOLOGY:-0}" = 1 ]; then
  step "SKIP_TOPOLOGY=1: compose topology not tried"
  step "container test passed"
  exit 0
fi

INFRA_IMAGE=localhost/efdm-infra:bookworm
INFRA_RECIPE=1  # bump when the Containerfile below changes
if [ "$(podman image inspect --format '{{index .Labels "efdm.infra.recipe"}}' "$INFRA_IMAGE" 2>/dev/null)" != "$INFRA_RECIPE" ]; then
  step "building $INFRA_IMAGE (Debian's redis-server and nginx, stand-ins for the official images)"
  workdir=$(mktemp -d "${TMPDIR:-/var/tmp}/efdm-infra.XXXXXX")
  {
    echo "FROM $BASE_IMAGE"
    echo "RUN apt-get update -qq \\"
    echo " && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends redis-server nginx-light >/dev/null \\"
    echo " && rm -rf /var/lib/apt/lists/* /etc/nginx/sites-enabled/default"
    echo "LABEL efdm.infra.recipe=$INFRA_RECIPE"
  } >"$workdir/Containerfile"
  podman build --quiet --format docker --tag "$INFRA_IMAGE" "$workdir" >/dev/null
  rm -rf "$workdir"
  workdir=""
fi

# compose.yaml's services as shell-quoted lines: "replicas NAME...", "env NAME K=V",
# "tmpfs NAME PATH", "read_only NAME", "redis_cmd ARG..."
topology=$("$PYTHON" -c '
import shlex
from tests.deploy._files import COMPOSE, interpolate, load_yaml

services = load_yaml(COMPOSE)["services"]
replicas = [n for n, s in services.items() if s.get("build", {}).get("dockerfile") == "docker/Dockerfile"]
print("replicas", *replicas)
for name in replicas:
    for key, value in services[name].get("environment", {}).items():
        print("env", name, shlex.quote(f"{key}={interpolate(str(value))}"))
    for path in services[name].get("tmpfs", []):
        print("tmpfs", name, shlex.quote(path))
    if services[name].get("read_only"):
        print("read_only", name)
# the official image adds --protected-mode no by itself; Debian redis-server needs it said
print("redis_cmd", *map(shlex.quote, services["redis"]["command"]), "--protected-mode", "no")
')
read -r -a replicas <<<"$(sed -n 's/^replicas //p' <<<"$topology")"
[ "${#replicas[@]}" -ge 2 ] || die "compose.yaml has fewer than two replicas"

network=efdm-test-$$
podman network create "$network" >/dev/null
run_on_network() {  # run_on_network ALIAS PODMAN-RUN-ARGS... (the compose service name as alias)
  local alias=$1
  shift
  containers+=("$alias-$$")
  podman run --detach --name "$alias-$$" --network "$network" --network-alias "$alias" \
    --no-healthcheck "$@" >/dev/null
}

step "redis, ${replicas[*]} and nginx on network $network"
eval "redis_cmd=($(sed -n 's/^redis_cmd //p' <<<"$topology"))"
run_on_network redis "$INFRA_IMAGE" "${redis_cmd[@]}"
replica_urls=()
for name in "${replicas[@]}"; do
  args=()
  eval "envs=($(sed -n "s/^env $name //p" <<<"$topology"))"
  for e in "${envs[@]}"; do args+=(--env "$e"); done
  eval "mounts=($(sed -n "s/^tmpfs $name //p" <<<"$topology"))"
  for t in "${mounts[@]}"; do args+=(--tmpfs "$t"); done
  # compose's read_only: only the tmpfs it lists are writable (podman would add more)
  if grep -qx "read_only $name" <<<"$topology"; then args+=(--read-only --read-only-tmpfs=false); fi
  # published for the test's direct checks only; compose publishes just nginx
  p=$(free_port)
  replica_urls+=("http://127.0.0.1:$p")
  run_on_network "$name" --publish "127.0.0.1:$p:8000" "${args[@]}" "$IMAGE"
done
for i in "${!replicas[@]}"; do
  wait_http "${replica_urls[$i]}/readyz" "${replicas[$i]}-$$"  # up, and Redis reached
done
lb_port=$(free_port)
run_on_network lb --publish "127.0.0.1:$lb_port:80" \
  --volume "$here/nginx.conf:/etc/nginx/conf.d/default.conf:ro" \
  "$INFRA_IMAGE" nginx -g 'daemon off; error_log stderr warn;'
wait_http "http://127.0.0.1:$lb_port/nginx-health" "lb-$$"

step "smoke test through nginx: frames, WebSocket, shared Redis, affinity by session"
replica_args=()
for u in "${replica_urls[@]}"; do replica_args+=(--replica "$u"); done
"$PYTHON" -m tests.deploy.container_smoke "http://127.0.0.1:$lb_port" "${replica_args[@]}"

step "readiness follows Redis: /readyz 503 (and /healthz 200) while it is stopped"
podman stop --time 5 "redis-$$" >/dev/null
"$PYTHON" -c '
import sys, time
import httpx
for url in sys.argv[1:]:
    deadline = time.monotonic() + 20
    while (code := httpx.get(f"{url}/readyz", timeout=5).status_code) != 503:
        assert time.monotonic() < deadline, f"{url}/readyz still {code} without Redis"
        time.sleep(0.5)
    assert httpx.get(f"{url}/healthz", timeout=5).status_code == 200, "liveness must not follow"
' "${replica_urls[@]}" || die "readiness does not follow Redis"

step "container test passed"
