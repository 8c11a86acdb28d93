// Dr.Bokeh backward pass 2 of 4 (per layer): each pixel x as a receiver, over its forward
// window (same loops as drbokeh_layer.comp): dL/dalpha_x and dL/ds_x, dL/drel_x through the
// occlusion O(y, x) and V_l(x), and dL/dV_l(x) / sum D (normalised adjoint of V for pass 4).
// CPU reference: src/render/drbokeh/backward_cpu.rs `own_pixel`.
//
// Bindings (set 0, std430), "read" = the uploaded rect pc.read (it holds the window of every
// receiver of the core pc.core: the same rects as the forward's):
//   0: rgba         readonly  vec4[layer_count * read pixels]
//   1: disparity    readonly  float[layer_count * read pixels]
//   2: tile_window  readonly  int[layer_count * tiles_x * tiles_y] whole image (forward pass 1)
//   3: area_lut     readonly  float[area_count]
//   4: kernel       readonly  float[max(1, kernel_size^2)]
//   5: adj_cw       readonly  vec4[layer_count * read pixels]  (backward pass 1, core entries)
//   6: adj_vis      readonly  float[layer_count * read pixels]
//   7: own          writeonly vec4[layer_count * read pixels]  (alpha, s, rel, V / sum D), core entries
//   8: receiver     writeonly vec4[layer_count * read pixels]  (rel_x, alpha_x, V / sum D, h_x), core
//                   entries: all pass 4 reads of a receiver, packed into one load per tap
// Push constants: DrBokehPush (leaky_slope included).
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer, after pass 1.
// Body (also of the disk path drbokeh_backward_own_disk.comp) and the taps it skips (exact
// zeros only): glsl/common/drbokeh_backward_own.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh_backward_own.glsl"
