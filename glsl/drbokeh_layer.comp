// Dr.Bokeh pass 2b of 3 (per layer): C_l, W_l and V_l of every pixel, gathered over its tile's
// window. C_l = sum_y P(y) S K O / A (P premultiplied RGB), W_l = sum_y a(y) S K O / A,
// V_l = soft-disk mean alpha over x's CoC (default) or the released square box (compat).
// CPU reference: src/render/drbokeh/cpu.rs `layer_pixel` (same taps, same order).
//
// Why it is faster than the first kernel (kept as glsl/drbokeh_layer_naive.comp, the
// benchmark baseline):
// - Taps outside the Euclidean disk of radius h + 1 are skipped: h = ceil(reach) - 1 and every
//   gauge is at least the Euclidean length, so their S, K and V terms are exactly 0 (pi/4 of
//   the square). Rows and columns are clipped to the image instead of tested per tap.
// - Default model, disk aperture (the common case): P / A(r_y), s_y and alpha_y come from the
//   per-source prepass (drbokeh_layer_sources.comp), one gauge serves the scatter and the
//   visibility, the in-layer occlusion is evaluated only for centres that can occlude
//   (alpha_x * in_focus(r_x) > 0; elsewhere O = 1 exactly), and each invocation gathers a
//   run of adjacent pixels from one load per source (loads are per-lane gathers on lavapipe).
//   Lanes whose centres cannot occlude run a loop without the occlusion terms, and there the
//   columns where every tap's smoothsteps are exactly 1 (from a per-tile lower bound of the
//   sources' |s|) add P / A and alpha without evaluating any term: one span sum per row
//   and invocation from global 16-px block sums (drbokeh_layer_blocks.comp), shared by the
//   run's centres. Same terms, another summation order (f32 rounding apart from the full
//   taps), yet every sum is a function of global positions: bit-identical for every tiling.
// - Layer by layer (pc.fold), a run of centres the layers in front hide completely
//   (transmittance exactly 0, as inside an opaque layer) returns before its gather: the
//   composite step would add exactly 0 and keep T = 0 (drbokeh_layer_hidden); so does every
//   tile no source of the layer reaches (drbokeh_layer_adds_nothing), before any per-pixel load.
// - Every other model or aperture runs the first kernel's per-tap terms over the clipped disk
//   (this file); the disk path is glsl/drbokeh_layer_disk.comp, the same body
//   (glsl/common/drbokeh_layer.glsl) with DRBOKEH_LAYER_DISK, which the host picks for the
//   default model with a disk aperture (`disk_path` in src/render/drbokeh/gpu.rs).
//
// Bindings (set 0, std430), "read" = the uploaded rect pc.read, "core" = the frame tile pc.core:
//   0: rgba         readonly  vec4[layer_count * read pixels]      premultiplied, layer-major
//   1: disparity    readonly  float[layer_count * read pixels]
//   2: tile_window  readonly  int[layer_count * tiles_x * tiles_y] whole image, bounds.rs
//   3: area_lut     readonly  float[area_count]                    Params::area_lut_f32
//   4: kernel       readonly  float[max(1, kernel_size^2)]         Params::kernel_f32
//   5: layer_cw     vec4[layer_count * core pixels]      (C_l.rgb, W_l); with pc.fold the
//                   running composite (premultiplied RGBA) of the layers so far, over the core
//   6: layer_vis    float[layer_count * core pixels]     V_l; with pc.fold the transmittance
//   7: source_pa    readonly  vec4[layer_count * read pixels]      P / A(r), prepass
//   8: source_sa    readonly  vec2[layer_count * read pixels]      (s, alpha), prepass
//   9: tile_radii   readonly  vec2[layer_count * tiles_x * tiles_y] whole image, bounds.rs
//                                 `disk_radii` (disk path only: its cheap interior taps and
//                                 the outer radius its rows are trimmed to)
//  10: block_prefix readonly vec4[layer_count * read pixels]      row block sums of P / A and
//  11: block_suffix readonly vec4[layer_count * read pixels]      alpha, prepass 2a'
//  12: block_alpha  readonly vec2[layer_count * read pixels]      (drbokeh_layer_blocks.comp)
// Push constants: DrBokehPush (all fields but max_support). The read rect holds every source
// within the window of every pixel of the core; borders are the image's, not the tile's.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer (the host asks
// groups_for(ceil(core width / RUN), core height): RUN pixels per invocation).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh_layer.glsl"
