#!/usr/bin/env bash
# `crowd report` of the seven benchmark scenes, every LOD mode, and the headline table.
#
#   scripts/report_seeds.sh                 # all seven scenes, modes none/triangles/points/clusters/auto
#   SCENES="poser4 horses" scripts/report_seeds.sh
#   FRAMES=6 SIZE=1280x720 scripts/report_seeds.sh
#
# One report per scene goes to $OUT/<scene>/ (index.html, report.json, plots, samples), so a scene that fails or is
# interrupted loses only its own report; $OUT/table.md is the headline table over all finished scenes (frame time
# p50/p95 and image error PSNR/SSIM/FLIP per scene and mode against the true reference -- full detail with 4 x 4
# samples per pixel, box-filtered, crowd.reference -- and PSNR against aliased full detail, a row of its own).
#
# Overrides (environment), chosen so that the seven scenes run in well under an hour on a 2-core llvmpipe machine:
#   FRAMES   frames per run (default 3: the first frames of each camera path; full detail of the big scenes takes
#            tens of seconds per frame: grid 576 M and stampede 242 M triangles)
#   SIZE     image size (default 640x360)
#   EVERY    compare every EVERY-th frame with its reference (default 2: frames 0 and 2, flicker of 0 -> 1)
#   MODES    the lod.mode sweep (default none,triangles,points,clusters,auto)
#   CLUSTER  --cluster of crowd report (default: the embedded dask LocalCluster; "none" runs in this process)
#   OUT      output folder (default out/report_seeds)
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
SCENES=${SCENES:-"poser4 horses stadium office exhibition grid stampede"}
FRAMES=${FRAMES:-3}
SIZE=${SIZE:-640x360}
EVERY=${EVERY:-2}
MODES=${MODES:-none,triangles,points,clusters,auto}
OUT=${OUT:-out/report_seeds}
mkdir -p "$OUT"
status=0
for s in $SCENES; do
  echo "== $s ($(date -u +%H:%M:%S) UTC)"
  start=$(date +%s)
  if "$PY" -m crowd report "scenes/$s.toml" --sweep "lod.mode=$MODES" --frames "$FRAMES" --size "$SIZE" \
       --sample-every "$EVERY" --out "$OUT/$s" ${CLUSTER:+--cluster "$CLUSTER"}; then
    echo "   $s: $(( $(date +%s) - start )) s"
  else
    status=$?
    echo "   $s: FAILED (exit $status) after $(( $(date +%s) - start )) s" >&2
  fi
done
"$PY" - "$OUT" $SCENES <<'EOF'
import json, sys
from pathlib import Path

out, scenes = Path(sys.argv[1]), sys.argv[2:]
num = lambda x, f: "–" if x is None else f.format(x)  # noqa: E731
rows = ["| scene | mode | p50 ms | p95 ms | triangles/frame | points/frame | PSNR dB | SSIM | FLIP | PSNR dB vs aliased |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
for s in scenes:
    f = out / s / "report.json"
    if not f.is_file():
        rows.append(f"| {s} | (no report) | | | | | | | | |")
        continue
    data = json.loads(f.read_text())
    for sc in data["scenes"]:
        for st in sc["settings"]:
            a, al, fm = st["accuracy"], st.get("accuracy_aliased") or {}, st["frame_ms"]
            psnr = "∞ (identical)" if a["psnr"] is None and a["identical"] else num(a["psnr"], "{:.1f}")
            psnr_al = "∞ (identical)" if al.get("psnr") is None and al.get("identical") else num(al.get("psnr"), "{:.1f}")
            mode = st["lod_mode"] + (" (aliased full detail)" if st.get("aliased_full_detail") else "")
            rows.append(f"| {sc['name']} | {mode} | {fm['p50']:.0f} | {fm['p95']:.0f} | "
                        f"{st['triangles']:,.0f} | {st['points']:,.0f} | {psnr} | {num(a['ssim'], '{:.4f}')} | "
                        f"{num(a['flip'], '{:.4f}')} | {psnr_al} |")
machine = next((json.loads((out / s / "report.json").read_text()).get("machine") for s in scenes
                if (out / s / "report.json").is_file()), None) or {}
text = "\n".join(rows) + "\n"
(out / "table.md").write_text(f"Machine: {machine.get('cpu')}, {machine.get('cores')} cores, "
                              f"{machine.get('gl_renderer')}\n\n" + text)
print(text)
EOF
exit $status
