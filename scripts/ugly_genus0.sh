#!/usr/bin/env bash
# The "ugly" genus-0 set of docs/robustness.md: per mesh `surfmap uniformize`,
# per pair `surfmap map` both ways; prints markdown table rows.
#   bash scripts/ugly_genus0.sh DIR   (DIR: where the meshes are / are written)
# DIR must already hold the decimated models dec_{bunny,spot}_{150,250,500,1000}.obj
# (scripts/decimate_blender.py from the shared meshes); the rest is generated.
set -uo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
S="${SURFMAP:-$repo/build/bin/surfmap}"
cd "$1"
gen() { [ -f "$1.obj" ] || "$S" generate "${@:2}" -o "$1.obj" >/dev/null; }
gen jittered_sphere sphere --subdivisions 4 --jitter 0.29 --seed 3
gen raw_peanut32 peanut --raw --resolution 32
gen raw_peanut48 peanut --raw --resolution 48
gen zero_area sphere --subdivisions 4 --degenerate 300 --degenerate-t 0.5
gen bent5 bent-sphere --rings 30 --segments 200 --stretch 5
gen bent10c bent-sphere --rings 20 --segments 60 --stretch 10
gen bent40c bent-sphere --rings 20 --segments 60 --stretch 40
min_angle() { python3 - "$1" <<'PY'
import math, sys
V, F = [], []
for line in open(sys.argv[1]):
    p = line.split()
    if p and p[0] == "v": V.append([float(x) for x in p[1:4]])
    if p and p[0] == "f": F.append([int(x.split("/")[0]) - 1 for x in p[1:4]])
best = 180.0
for f in F:
    for k in range(3):
        a, b, c = V[f[k]], V[f[(k + 1) % 3]], V[f[(k + 2) % 3]]
        u = [b[i] - a[i] for i in range(3)]; w = [c[i] - a[i] for i in range(3)]
        nu, nw = math.sqrt(sum(x * x for x in u)), math.sqrt(sum(x * x for x in w))
        if nu == 0 or nw == 0: best = 0.0; continue
        d = max(-1.0, min(1.0, sum(u[i] * w[i] for i in range(3)) / (nu * nw)))
        best = min(best, math.degrees(math.acos(d)))
print("%.2g°" % best)
PY
}
field() { python3 -c "import json,sys;r=json.load(open('$1'));print(eval(sys.argv[1]))" "$2" 2>/dev/null; }
meshes="${MESHES:-dec_bunny_150 dec_bunny_250 dec_bunny_500 dec_bunny_1000 dec_spot_250 dec_spot_500 dec_spot_1000 jittered_sphere raw_peanut32 raw_peanut48 zero_area bent5 bent10c bent40c}"
echo "| mesh | V | min angle | converged | flipped / input flipped | time |"
echo "|---|---|---|---|---|---|"
for m in $meshes; do
  /usr/bin/time -f %e -o u_$m.time timeout 600 "$S" uniformize $m.obj --report u_$m.json --quiet >/dev/null 2>u_$m.err
  echo "| $m | $(field u_$m.json "r['vertices']") | $(min_angle $m.obj) | $(field u_$m.json "r['converged']") | $(field u_$m.json "str(r.get('flipped_faces'))+' / '+str(r.get('input_flipped_faces'))") | $(tail -1 u_$m.time) s $(head -c 120 u_$m.err) |"
done
pairs="${PAIRS:-dec_bunny_150:dec_spot_250 dec_bunny_250:dec_spot_250 dec_bunny_500:dec_spot_500 dec_spot_1000:raw_peanut32 zero_area:dec_bunny_250 bent5:dec_spot_500 bent40c:bent10c raw_peanut48:dec_bunny_1000 jittered_sphere:dec_bunny_500}"
echo
echo "| pair | converged | flipped | repaired | subdivision: status, inverted / subdivided faces, new vertices (bends), cover | D' mean / max | time |"
echo "|---|---|---|---|---|---|---|"
for p in $pairs; do
  a=${p%%:*}; b=${p#*:}
  for dir in "$a $b" "$b $a"; do
    set -- $dir
    n=m_$1__$2
    /usr/bin/time -f %e -o $n.time timeout 600 "$S" map $1.obj $2.obj --out $n.obj --report $n.json --quiet >/dev/null 2>$n.err
    echo "| $1 -> $2 | $(field $n.json "r['converged']") | $(field $n.json "r['flipped_triangles']") | $(field $n.json "r['repaired_vertices']") | $(field $n.json "(lambda s: (s['status'] or 'none')+', '+str(s['inverted_faces'])+' / '+str(s['subdivided_faces'])+', '+str(s['new_vertices'])+' ('+str(s.get('bends'))+'), '+('%.9f'%s['sphere_cover']))(r['source_subdivision'])") | $(field $n.json "'%.3f / %.3g'%(r['distortion']['mean'],r['distortion']['max'])") | $(tail -1 $n.time) s $(head -c 160 $n.err) |"
  done
done
