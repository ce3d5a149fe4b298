#!/usr/bin/env bash
# The mutation check (issue 13 section 7): break each culling method's and each PVS method's core
# test on purpose (answer "visible" always, "hidden" always, skip the occluder, ignore the PVS) and
# check that a test fails. Nothing is changed in place: the tracked and untracked files of this tree
# are copied to /tmp/slmUID/t (SL_MUTANTS_DIR), the tests the chosen mutants name must pass there
# unmutated (the baseline), then each mutant is applied there to one file with a
# perl substitution, only the test programs that mutant names are rebuilt (ccache keeps it short),
# and those tests run. A mutant is KILLED when a test fails, SURVIVED when every test passes, and an
# ERROR when its substitution no longer matches the source or the mutated tree does not build (then
# fix the table below). Exit status: 0 when every mutant chosen was killed.
#
#   scripts/mutants.sh --list          the mutants, their file and tests
#   scripts/mutants.sh [NAME...]       run the named ones (default: all); NAME may be a glob (hzb-*)
#   scripts/mutants.sh --ci            the short set CI runs (.ci/run)
#   SL_MUTANTS_DIR=DIR                 work directory (default: /tmp/slmUID; keep its path short)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

# name @@ file @@ perl -0 substitution (must change the file) @@ tests
# Tests are CTest names; test_* programs are rebuilt, cli_* tests rebuild the command.
mutants=(
  # ---- culling methods ----
  'vfc-visible@@src/cull/vfc.c@@s/(bool coherence, bool masks\)\n\{\n)/$1    if (pl) return 0;\n/@@test_method_own test_culler'
  'hzb-visible@@src/cull/hzb.c@@s/(    f->st->occlusion_tests\+\+;\n    hzb_state \*s = f->s;\n)/$1    if (f) return false;\n/@@test_method_own test_occlusion'
  'hzb-hidden@@src/cull/hzb.c@@s/(    f->st->occlusion_tests\+\+;\n    hzb_state \*s = f->s;\n)/$1    if (f) return true;\n/@@test_method_own test_occlusion'
  'lazygrid-visible@@src/cull/lazygrid.c@@s/(static bool occluded_obuf\(lg_state \*s, const sl_occ_rect \*r\)\n\{\n)/$1    if (s) return false;\n/@@test_method_own test_occlusion'
  'lazygrid-z-visible@@src/cull/lazygrid.c@@s/(static bool occluded_z\(lg_state \*s, const sl_occ_rect \*r\)\n\{\n)/$1    if (s) return false;\n/@@test_method_own test_occlusion'
  'grid-hidden@@src/cull/lazygrid.c@@s/(static bool occluded_obuf\(lg_state \*s, const sl_occ_rect \*r\)\n\{\n)/$1    if (s) return true;\n/@@test_method_own test_occlusion'
  'hom-visible@@src/cull/hom.c@@s/(    st->occlusion_tests\+\+;\n    if \(!overlap_covered)/    st->occlusion_tests++;\n    if (s) return false;\n    if (!overlap_covered/@@test_method_own test_occlusion'
  'hom-deb-ignored@@src/cull/hom.c@@s/if \(!\(r\.dnear < s->deb\[/if (0 \&\& !(r.dnear < s->deb[/@@test_method_own test_occlusion test_occlusion_oracle'
  'frusta-visible@@src/cull/frusta.c@@s/(static bool in_shadow\(const shadow \*sh, const sl_aabb \*b, const sl_occ_view \*v, float rmax\)\n\{\n)/$1    if (sh) return false;\n/@@test_method_own test_occlusion'
  'frusta-hidden@@src/cull/frusta.c@@s/(static bool in_shadow\(const shadow \*sh, const sl_aabb \*b, const sl_occ_view \*v, float rmax\)\n\{\n)/$1    if (sh) return true;\n/@@test_method_own test_occlusion'
  'plp-no-budget@@src/cull/plp.c@@s/while \(s->heap_n && f\.tris < s->cfg\.c\.budget\)/while (s->heap_n)/@@test_method_own test_occlusion'
  'cplp-visible@@src/cull/plp.c@@s/return sl_occ_raster_test\(&f->s->r, r\.x0, r\.y0, r\.x1, r\.y1, r\.dnear\) == SL_RASTER_VISIBLE;/return true;/@@test_method_own test_occlusion'
  'cplp-hidden@@src/cull/plp.c@@s/return sl_occ_raster_test\(&f->s->r, r\.x0, r\.y0, r\.x1, r\.y1, r\.dnear\) == SL_RASTER_VISIBLE;/return false;/@@test_method_own test_occlusion test_occlusion_oracle'
  'hole-facing-ignored@@src/cull/occlusion/inner_coverage.c@@s/ok = !hull_facing\(v, nrm, a\);/ok = true || !hull_facing(v, nrm, a);/@@test_resolution'
  'hull-focal-min@@src/cull/occlusion/inner_coverage.c@@s/\* \(double\)v->focal_max \* dmax;/* (double)v->focal * dmax;/@@test_resolution'
  'occ-focal-max@@src/cull/occlusion/view.c@@s/v->focal = \(float\)fmin\(/v->focal = (float)fmax(/@@test_occlusion'
  'occ-near-reach-plane@@src/cull/occlusion/view.c@@s/double nr = v->ortho \? 0 : view->near_corner_dist;/double nr = v->ortho ? 0 : view->near_plane;/@@test_occlusion'
  'occluder-skipped@@src/cull/occlusion/raster.c@@s/(uint32_t sl_occ_raster_render\([^)]*\)\n\{\n)/$1    if (n) return 0;\n/@@test_method_own test_occlusion'
  'cullmap-visible@@src/cull/cullmap.c@@s/if \(czrow\[bi\] >= ctrow\[bi\]\) \{/if (0 \&\& czrow[bi] >= ctrow[bi]) {/; s/if \(!\(g->max_z\[c\] > zc\)\)/if (0 \&\& !(g->max_z[c] > zc))/; s/\|\| !\(u->boxes\[o\]\.max\.z > zc\)\)/|| (0 \&\& !(u->boxes[o].max.z > zc)))/@@test_method_own test_cullmap'
  'cullmap-hidden@@src/cull/cullmap.c@@s/\|\| !\(u->boxes\[o\]\.max\.z > zc\)\)/|| 1 || !(u->boxes[o].max.z > zc))/@@test_method_own test_cullmap test_urban_oracle'
  # (edge_hidden answering "no" always only draws edges the map already hides: an equivalent mutant)
  'cullmap-edge-skipped@@src/cull/cullmap.c@@s/(static bool edge_hidden\(const cullmap_state \*s, uint32_t e, bool coarse_only\)\n\{\n)/$1    if (s) return true;\n/@@test_method_own test_cullmap test_urban_oracle'
  'horizon-visible@@src/cull/horizon.c@@s/if \(!sl_horizon_occluded\(h, a0, span, top, bottom\)\)/if (1 || !sl_horizon_occluded(h, a0, span, top, bottom))/; s/if \(sl_horizon_occluded\(h, a0, span, hi, lo\)\)/if (0 \&\& sl_horizon_occluded(h, a0, span, hi, lo))/@@test_method_own test_horizon'
  'horizon-hidden@@src/cull/horizon.c@@s/if \(!sl_horizon_occluded\(h, a0, span, top, bottom\)\)/if (0 \&\& !sl_horizon_occluded(h, a0, span, top, bottom))/@@test_method_own test_horizon test_urban_oracle'
  # (the delta-H skip answering "no" always is an equivalent mutant: it almost never fires, docs/urban.md)
  'dhorizon-no-reuse@@src/cull/dhorizon.c@@s/bool reuse = s->have_prev && /bool reuse = false \&\& s->have_prev \&\& /@@test_method_own test_horizon'
  'dhorizon-reuse-all@@src/cull/dhorizon.c@@s/(    \(void\)id;\n)/$1    if (s) return true;\n/@@test_method_own test_horizon test_urban_oracle'
  'hoq-visible@@src/cull/hoq.c@@s/    return samples > 0;/    return true;/@@test_backend'
  'hoq-hidden@@src/cull/hoq.c@@s/    return samples > 0;/    return false;/@@test_backend'
  'hoq-near-queried@@src/cull/hoq.c@@s/if \(!\(z >= -w\) \|\| !\(w > 0\)\)/if (0 \&\& z < -w \&\& w > 0)/g@@test_backend'
  'hoq-no-margin@@src/cull/hoq.c@@s/float m = \(float\)\(v->margin \* px/float m = 0 * (float)(v->margin * px/@@test_backend'
  'hoq-no-reach@@src/cull/hoq.c@@s/    if \(!v->reach\)\n        return true;/    if (v->reach)\n        return true;/@@test_backend'
  'backend-no-latency@@src/cull/backend_cpu.c@@s/s->ready_frame = b->frame \+ b->latency;/s->ready_frame = b->frame;/@@test_backend'
  'backend-no-clock-latency@@src/cull/backend_cpu.c@@s/s->ready_ns = b->now \+ b->clock.query_latency_ns;/s->ready_ns = b->now;/@@test_query_cullers'
  'chc-no-pullup@@src/cull/chc.c@@s/while \(n != SL_NONE && !s->visible\[n\]\) \{/while (0 \&\& n != SL_NONE \&\& !s->visible[n]) {/@@test_query_cullers'
  'chc-drop-result@@src/cull/chc.c@@s/            traverse\(f, r->node\);\n        \} else \{/            (void)0;\n        } else {/@@test_query_cullers'
  'chc-near-queried@@src/cull/chc.c@@s/if \(!queryable \|\| !f->drawn_any\) \{/if (!f->drawn_any) {/@@test_query_cullers'
  'chcpp-no-split@@src/cull/chc.c@@s/                issue_i\(f, n\); \/\* split: one query a node \*\//                s->invisible_for[n]++;/@@test_query_cullers'
  'chc-no-refit@@src/cull/chc.c@@s/(static sl_status chc_scene_changed\(void \*state, sl_error \*err\)\n\{\n)/$1    if (state) return SL_OK;\n/@@test_query_cullers'
  'chcpp-v-undrawn@@src/cull/chc.c@@s/            render_leaf\(f, n\);\n            s->vpend\[s->vpend_n\+\+\] = n;/            s->vpend[s->vpend_n++] = n;/@@test_query_cullers'
  'pvs-everything@@src/cull/pvs.c@@s/bool all = cell == SL_NONE;/bool all = true;/@@test_pvs_build test_domain'
  'pvs-no-frustum@@src/cull/pvs.c@@s/sl_frustum_classify_box\(fr->planes, slack, &bounds\[id\], 0x3fu, false, NULL\) >= 0/fr/@@test_pvs_build test_domain'
  'pvs-cell-only@@src/cull/pvs.c@@s/uint32_t nc = sl_viewcells_overlap\(s->cells, s->scene, &nb, s->near_cells, s->cell_count, &covered\);/uint32_t nc = 1; covered = true; s->near_cells[0] = cell; (void)nb;/@@test_pvs_build test_near_wall'
  # ---- PVS methods ----
  'sample-all@@src/region/method_sample.c@@s/if \(w->state\[o\] == 1\)\n(\s*)out->ids\[n\+\+\] = o;/out->ids[n++] = o;/@@test_pvs_build'
  'sample-none@@src/region/method_sample.c@@s/out->count = n;\n    out->work = written;/out->count = 0;\n    out->work = written;/@@test_pvs_build'
  'adjustable-all@@src/region/method_adjustable.c@@s/(    memcpy\(out->ids, w->cand, \(size_t\)nc \* sizeof\(uint32_t\)\);)/    nc = s->nobj;\n    for (uint32_t q_ = 0; q_ < nc; q_++)\n        w->cand[q_] = q_;\n$1/@@test_pvs_build test_bake_files'
  'extproj-all@@src/region/method_extproj.c@@s/if \(!w->hidden\[o\]\)\n(\s*)out->ids\[m\+\+\] = o;/out->ids[m++] = o;/@@test_extproj'
  'extproj-union@@src/region/method_extproj.c@@s/(        if \(h < 3\)\n            return 0;\n)/$1        if (e > 0) { memcpy(w->fp3, res, 2 * (size_t)cnt * sizeof(double)); memcpy(w->fp3 + 2 * cnt, w->hull, 2 * (size_t)h * sizeof(double)); cnt = hull(w->fp3, cnt + h, res); continue; }\n/@@test_extproj'
  'extproj-no-depth@@src/region/method_extproj.c@@s/\(int32_t\)fj0, \(int32_t\)fj1, nf\)/(int32_t)fj0, (int32_t)fj1, FLT_MAX)/@@test_extproj'
  'mappvs-all@@src/region/method_mappvs.c@@s/if \(mark\[id\] \|\| !in_leaf\[id\]\)/if (mark)/@@test_portal'
  'portal-all@@src/region/method_portal.c@@s/if \(w->mark\[id\]\)\n(\s*)out->ids\[n\+\+\] = id;/out->ids[n++] = id;/@@test_portal'
  'gvs-all@@src/region/gvs.c@@s/    out->count = r\.object_count;/    for (uint32_t q_ = 0; q_ < w->g->nobj; q_++)\n        out->ids[q_] = q_;\n    out->count = w->g->nobj;/@@test_gvs'
  'shrink-none@@src/region/shrink.c@@s/(    if \(mode != SL_SHRINK_CYLINDER && mode != SL_SHRINK_BALL\)\n)/    eps = 0;\n$1/@@test_shrink test_pvs_build'
  'cells-locate-none@@src/pvs/viewcells.c@@s/(uint32_t sl_viewcells_locate\(sl_viewcells v, sl_scene scene, sl_vec3 p\)\n\{\n)/$1    if (v) return SL_NONE;\n/@@test_viewcells test_pvs_build'
)

# the fields are separated by @@ (the substitutions hold | and /)
field() {
  local rest="$1" i
  for ((i = 0; i < $2; i++)); do rest="${rest#*@@}"; done
  printf '%s' "${rest%%@@*}"
}

if [ "${1:-}" = "--list" ]; then
  for m in "${mutants[@]}"; do printf '%-20s %-32s %s\n' "$(field "$m" 0)" "$(field "$m" 1)" "$(field "$m" 3)"; done
  exit 0
fi
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi

# the short set of .ci/run: one mutant a family, none that needs test_pvs_build but the pvs culler's
ci_set=(vfc-visible hzb-visible lazygrid-visible hom-visible frusta-visible cplp-visible cullmap-visible
  horizon-visible dhorizon-no-reuse portal-all gvs-all chc-drop-result chc-no-pullup)
if [ "${1:-}" = "--ci" ]; then
  set -- "${ci_set[@]}"
fi

chosen=()
for m in "${mutants[@]}"; do
  name="$(field "$m" 0)"
  if [ $# -eq 0 ]; then chosen+=("$m"); continue; fi
  for pat in "$@"; do
    # shellcheck disable=SC2053
    if [[ "$name" == $pat ]]; then chosen+=("$m"); break; fi
  done
done
[ ${#chosen[@]} -gt 0 ] || { echo "mutants.sh: no mutant matches: $* (see --list)" >&2; exit 2; }

# A short path: test_pvs_build's messages quote file paths in a 512-byte sl_error, and a long
# build path truncates them (its test_checkpoint_lock then fails on the unmutated tree).
work="${SL_MUTANTS_DIR:-/tmp/slm$(id -u)}"
tree="$work/t"
# the copy and its build sit like the source and build/ do, and every path is hashed relative to
# the build directory (CCACHE_BASEDIR=/), so ccache finds what the usual build compiled
export CCACHE_BASEDIR=/ CCACHE_NOHASHDIR=true
start=$(date +%s)
echo "== copying the tree to $tree"
rm -rf "$tree"
mkdir -p "$tree"
(cd "$root" && git ls-files -co --exclude-standard -z | grep -zv '^build' | tar --null -T - -cf -) | (cd "$tree" && tar -xf -)
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache)
cmake -S "$tree" -B "$tree/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSL_WERROR=ON -DSL_BUILD_BENCH=OFF \
  "${launcher[@]}" >"$work/configure.log" 2>&1 || { cat "$work/configure.log"; exit 2; }
jobs="${SL_MUTANTS_JOBS:-2}"

# build the test programs (and the command for cli_ tests) a mutant names
targets_of() {
  local t out=()
  for t in $1; do
    case "$t" in cli_*) out+=(sightline_cli) ;; *) out+=("$t") ;; esac
  done
  printf '%s\n' "${out[@]}" | sort -u | tr '\n' ' '
}

# the baseline: the tests the chosen mutants name must pass on the unmutated copy, else a failure
# says nothing about a mutant
all_tests="$(for m in "${chosen[@]}"; do field "$m" 3; echo; done | tr ' ' '\n' | sort -u | tr '\n' ' ')"
echo "== baseline (unmutated): $all_tests"
t0=$(date +%s)
cmake --build "$tree/build" -j"$jobs" --target $(targets_of "$all_tests") >"$work/baseline.build.log" 2>&1 ||
  { echo "mutants.sh: the unmutated copy does not build: $work/baseline.build.log" >&2; exit 2; }
if ! (cd "$tree/build" && ctest -R "^($(echo $all_tests | tr ' ' '|'))\$" -j"$jobs" --timeout 600 --output-on-failure \
  >"$work/baseline.test.log" 2>&1); then
  echo "mutants.sh: tests fail on the unmutated copy (fix them first): $work/baseline.test.log" >&2
  grep -E '(Failed|Timeout)' "$work/baseline.test.log" >&2 || true
  exit 2
fi
echo "   passed ($(($(date +%s) - t0)) s)"

declare -a results
killed=0 survived=0 errors=0
for m in "${chosen[@]}"; do
  name="$(field "$m" 0)" file="$(field "$m" 1)" sub="$(field "$m" 2)" tests="$(field "$m" 3)"
  t0=$(date +%s)
  cp "$root/$file" "$tree/$file"
  status=
  if ! perl -0pi -e "$sub" "$tree/$file" || cmp -s "$root/$file" "$tree/$file"; then
    status=ERROR
    why="substitution does not match $file"
  elif ! cmake --build "$tree/build" -j"$jobs" --target $(targets_of "$tests") >"$work/$name.build.log" 2>&1; then
    status=ERROR
    why="does not build (see $work/$name.build.log)"
  else
    regex="^($(echo $tests | tr ' ' '|'))\$"
    if (cd "$tree/build" && ctest -R "$regex" -j"$jobs" --timeout 600 --output-on-failure >"$work/$name.test.log" 2>&1); then
      status=SURVIVED
      why="every test passed: $tests"
    else
      status=KILLED
      why="failed: $(grep -oE '[0-9]+ - [A-Za-z0-9_]+ \((Failed|Timeout|SEGFAULT|Subprocess aborted|Exception)[^)]*\)' "$work/$name.test.log" | sed 's/^[0-9]* - //' | tr '\n' ' ')"
    fi
  fi
  cp "$root/$file" "$tree/$file"
  case $status in KILLED) killed=$((killed + 1)) ;; SURVIVED) survived=$((survived + 1)) ;; *) errors=$((errors + 1)) ;; esac
  line="$(printf '%-20s %-8s %4ss  %s' "$name" "$status" "$(($(date +%s) - t0))" "$why")"
  echo "$line"
  results+=("$line")
done
# leave the copy unmutated and its programs rebuilt from the true sources
echo "== summary: ${#chosen[@]} mutants, $killed killed, $survived survived, $errors errors ($(($(date +%s) - start)) s)"
for r in "${results[@]}"; do echo "  $r"; done
[ "$survived" -eq 0 ] && [ "$errors" -eq 0 ]
