// bench_identity: how far a map of a shape onto (a meshing of) the same shape is from the identity.
// Used by the held-out sweep (docs/history/robustness.md, "Held-out sweep, 2026-12-03").
//
//   bench_identity SOURCE.obj TARGET.obj MORPH.obj      (MORPH.obj: surfmap map ... --out)
//
// Identity error of a morph: for source vertex i (A_i), morph vertex O_i (its image on B):
//   e_self = |O_i - A_i| / diag(A)          (mapping a shape to (a meshing of) the same shape)
//   e_proj = |O_i - P_i| / diag(A), P_i = nearest point of B to A_i (the morph vs the nearest point on the target)
//   gap    = |A_i - P_i| / diag(A)          (how far apart the two meshings are)
// prints mean/max of each.
#include <cstdio>
#include <cmath>
#include <vector>
#include <string>
#include <fstream>
#include <sstream>
#include <array>
#include <unordered_map>
#include <algorithm>
#include <stdexcept>
using V3 = std::array<double, 3>;
static void readObj(const char* p, std::vector<V3>& v, std::vector<std::array<int, 3>>& f) {
  std::ifstream in(p); std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line); std::string t; s >> t;
    if (t == "v") { V3 x; s >> x[0] >> x[1] >> x[2]; v.push_back(x); }
    else if (t == "f") { std::vector<int> ids; std::string w; while (s >> w) ids.push_back(std::stoi(w.substr(0, w.find('/'))) - 1);
      for (size_t k = 1; k + 1 < ids.size(); ++k) f.push_back({ids[0], ids[k], ids[k + 1]}); }
  }
}
static V3 sub(V3 a, V3 b) { return {a[0]-b[0], a[1]-b[1], a[2]-b[2]}; }
static double dot(V3 a, V3 b) { return a[0]*b[0]+a[1]*b[1]+a[2]*b[2]; }
static V3 add(V3 a, V3 b, double s) { return {a[0]+s*b[0], a[1]+s*b[1], a[2]+s*b[2]}; }
static V3 closest(V3 p, V3 a, V3 b, V3 c) {  // Ericson, Real-Time Collision Detection 5.1.5
  V3 ab = sub(b,a), ac = sub(c,a), ap = sub(p,a);
  double d1 = dot(ab,ap), d2 = dot(ac,ap); if (d1 <= 0 && d2 <= 0) return a;
  V3 bp = sub(p,b); double d3 = dot(ab,bp), d4 = dot(ac,bp); if (d3 >= 0 && d4 <= d3) return b;
  double vc = d1*d4 - d3*d2; if (vc <= 0 && d1 >= 0 && d3 <= 0) return add(a, ab, d1/(d1-d3));
  V3 cp = sub(p,c); double d5 = dot(ab,cp), d6 = dot(ac,cp); if (d6 >= 0 && d5 <= d6) return c;
  double vb = d5*d2 - d1*d6; if (vb <= 0 && d2 >= 0 && d6 <= 0) return add(a, ac, d2/(d2-d6));
  double va = d3*d6 - d5*d4; if (va <= 0 && (d4-d3) >= 0 && (d5-d6) >= 0) return add(b, sub(c,b), (d4-d3)/((d4-d3)+(d5-d6)));
  double den = 1/(va+vb+vc); return add(add(a, ab, vb*den), ac, vc*den);
}
static int run(int argc, char** argv) {
  if (argc < 4) { fprintf(stderr, "ident A.obj B.obj morph.obj\n"); return 2; }
  std::vector<V3> A, B, O; std::vector<std::array<int,3>> FA, FB, FO;
  readObj(argv[1], A, FA); readObj(argv[2], B, FB); readObj(argv[3], O, FO);
  if (A.empty() || B.empty() || FB.empty()) { fprintf(stderr, "bench_identity: no vertices or faces read from %s or %s\n", argv[1], argv[2]); return 1; }
  for (const auto& f : FB) for (int v : f) if (v < 0 || v >= (int)B.size()) { fprintf(stderr, "bench_identity: %s: face index out of range\n", argv[2]); return 1; }
  if (O.size() != A.size()) { printf("morph has %zu vertices, source %zu\n", O.size(), A.size()); return 1; }
  V3 lo = A[0], hi = A[0]; for (auto& p : A) for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], p[k]); hi[k] = std::max(hi[k], p[k]); }
  double diag = std::sqrt(dot(sub(hi,lo), sub(hi,lo)));
  V3 blo = B[0], bhi = B[0]; for (auto& p : B) for (int k = 0; k < 3; ++k) { blo[k] = std::min(blo[k], p[k]); bhi[k] = std::max(bhi[k], p[k]); }
  double cell = std::sqrt(dot(sub(bhi,blo), sub(bhi,blo))) / 100;
  auto key = [&](long x, long y, long z) { return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791); };
  std::unordered_map<long, std::vector<int>> grid;
  for (int t = 0; t < (int)FB.size(); ++t) {
    V3 l = B[FB[t][0]], h = l; for (int j = 1; j < 3; ++j) for (int k = 0; k < 3; ++k) { l[k] = std::min(l[k], B[FB[t][j]][k]); h[k] = std::max(h[k], B[FB[t][j]][k]); }
    for (long x = std::floor((l[0]-blo[0])/cell); x <= std::floor((h[0]-blo[0])/cell); ++x)
      for (long y = std::floor((l[1]-blo[1])/cell); y <= std::floor((h[1]-blo[1])/cell); ++y)
        for (long z = std::floor((l[2]-blo[2])/cell); z <= std::floor((h[2]-blo[2])/cell); ++z) grid[key(x,y,z)].push_back(t);
  }
  double s1 = 0, m1 = 0, s2 = 0, m2 = 0, s3 = 0, m3 = 0;
  for (size_t i = 0; i < A.size(); ++i) {
    V3 p = A[i]; long cx = std::floor((p[0]-blo[0])/cell), cy = std::floor((p[1]-blo[1])/cell), cz = std::floor((p[2]-blo[2])/cell);
    double best = 1e300; V3 bp{};
    for (int r = 0; r < 200; ++r) {
      for (long x = cx-r; x <= cx+r; ++x) for (long y = cy-r; y <= cy+r; ++y) for (long z = cz-r; z <= cz+r; ++z) {
        if (std::max({std::labs(x-cx), std::labs(y-cy), std::labs(z-cz)}) != r) continue;
        auto it = grid.find(key(x,y,z)); if (it == grid.end()) continue;
        for (int t : it->second) { V3 q = closest(p, B[FB[t][0]], B[FB[t][1]], B[FB[t][2]]); double d = dot(sub(q,p), sub(q,p)); if (d < best) { best = d; bp = q; } }
      }
      if (best < 1e299 && std::sqrt(best) <= r * cell) break;
    }
    double e1 = std::sqrt(dot(sub(O[i],A[i]), sub(O[i],A[i]))) / diag, e2 = std::sqrt(dot(sub(O[i],bp), sub(O[i],bp))) / diag, e3 = std::sqrt(best) / diag;
    s1 += e1; m1 = std::max(m1, e1); s2 += e2; m2 = std::max(m2, e2); s3 += e3; m3 = std::max(m3, e3);
  }
  double n = A.size();
  printf("self %.3f%% / %.3f%%  proj %.3f%% / %.3f%%  gap %.3f%% / %.3f%%\n", 100*s1/n, 100*m1, 100*s2/n, 100*m2, 100*s3/n, 100*m3);
  return 0;
}

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    fprintf(stderr, "bench_identity: %s (reading the OBJ files)\n", e.what());
    return 1;
  }
}
