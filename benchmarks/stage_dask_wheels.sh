#!/usr/bin/env bash
# Stage warp-lang and every other wheel that benchmarks/bench_multigpu.py needs on the GPU machine
# (no package index there; its image has numpy 2.5, scipy, matplotlib, click, jinja2, pyyaml, fsspec,
# packaging, urllib3, but no Dask, trimesh or colour-science -- /work/.library/device/KINDS.md):
#
#   dask, distributed and what distributed needs beyond that image (tornado, zict, tblib, partd,
#   locket), with cloudpickle, msgpack, psutil, toolz, sortedcontainers at the versions the tests
#   pass with here -- for --executor dask;
#   trimesh (>= 4.4.0: older releases call ndarray.ptp, which NumPy 2 removed) and colour-science --
#   for --workload render (the still-life scene's meshes, the spectral-to-colour tables).
#
# Versions are those of this project's Python environment (PYTHON, default .venv/bin/python, else python3),
# so the GPU runs use the same Dask as the CPU tests. It calls ../shared/gpu/stage-warp.sh, which splits
# warp-lang into .dev-wheel-1..N (48 MiB each; see its header), and moves the extras (14 MiB) from the
# last part into .dev-wheel-extra (one part plus the 7 MiB tree must stay under 64 MiB a call).
#
# Usage (from the project root):   benchmarks/stage_dask_wheels.sh [WARP_VERSION]
#
# Then, on the device machine, back to back (it keeps /tmp only while warm):
#   run carry=[".dev-wheel-extra"]  command: mkdir -p /tmp/wh && cp .dev-wheel-extra/* /tmp/wh/
#   run carry=[".dev-wheel-K"]  command: mkdir -p /tmp/wh && cp .dev-wheel-K/* /tmp/wh/      (K = 1 .. N-1)
#   run carry=[".dev-wheel-N"]  command: mkdir -p /tmp/wh && cp .dev-wheel-N/* /tmp/wh/ &&
#       bash /tmp/wh/install-on-gpu.sh && export PYTHONPATH=/tmp/site:$PWD &&
#       python3 benchmarks/bench_multigpu.py --workload psf-map --size large,groups=36 --devices all \
#           --executor thread,process,dask
set -euo pipefail
warp_ver="${1:-1.19.0}"
root=$(git rev-parse --show-toplevel)
cd "$root"
py="${PYTHON:-}"
if [ -z "$py" ]; then
  if [ -x .venv/bin/python ]; then py=.venv/bin/python; else py=python3; fi
fi
pkgs=(dask distributed tornado zict tblib partd locket cloudpickle msgpack psutil toolz sortedcontainers
      trimesh colour-science)
specs=$("$py" - "${pkgs[@]}" <<'EOF'
import sys
from importlib import metadata

missing = []
out = []
for name in sys.argv[1:]:
    try:
        out.append(f"{name}=={metadata.version(name)}")
    except metadata.PackageNotFoundError:
        missing.append(name)
if missing:
    sys.exit(f"stage_dask_wheels.sh: {' '.join(missing)} not installed in {sys.executable}: "
             "pip install them there (or set PYTHON to the project's interpreter)")
print(" ".join(out))
EOF
)
tm=$(echo "$specs" | tr ' ' '\n' | sed -n 's/^trimesh==//p')
"$py" - "$tm" <<'EOF'
import sys
v = tuple(int(p) for p in sys.argv[1].split(".")[:3] if p.isdigit())
if v < (4, 4, 0):
    sys.exit(f"stage_dask_wheels.sh: trimesh {sys.argv[1]} predates NumPy 2 support (needs >= 4.4.0)")
EOF
shared="${LENSRT_SHARED:-}"
for cand in "$root/../shared" "$root/../../shared"; do
  if [ -z "$shared" ] && [ -x "$cand/gpu/stage-warp.sh" ]; then shared="$cand"; fi
done
if [ -z "$shared" ]; then
  echo "stage_dask_wheels.sh: ../shared/gpu/stage-warp.sh not found; set LENSRT_SHARED to the shared folder" >&2
  exit 2
fi
echo "staging warp-lang==$warp_ver and: $specs"
# shellcheck disable=SC2086  # one pip spec per word
"$shared/gpu/stage-warp.sh" "$warp_ver" $specs
# the extras would make the last part too big to travel with the tree (64 MiB a call): they get a part of their own
last=$(ls -d .dev-wheel-[0-9]* | sort -V | tail -1)
mkdir -p .dev-wheel-extra
mv "$last"/*.whl .dev-wheel-extra/
# the parts are git-ignored (.gitignore: /.dev-wheel-*/), so they travel only where a run carries them
du -sh .dev-wheel-* | sed 's/^/  /'
echo "order of the runs: .dev-wheel-extra, then .dev-wheel-1 .. $last (the last one installs; see this script's header)"
echo "each run carries one part plus the tracked tree ($(git ls-files -z | du -ch --files0-from=- | tail -1 | cut -f1)): keep both under 64 MiB"
