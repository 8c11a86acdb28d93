// Dr.Bokeh backward pass 4 of 4 (per layer): each pixel y as a source, gathered over every
// receiver x whose forward window holds y (|x - y| within x's tile window): dL/d(premultiplied
// RGBA) through C/W and V, dL/ds_y and dL/drel_y through the weight; plus pass 2's terms.
// Writes the final gradients and rel_y * dL/ds_y, y's share of dL/dK (summed on the host).
// CPU reference: src/render/drbokeh/backward_cpu.rs `source_pixel`.
//
// Bindings (set 0, std430), "core" = pc.core, the sources this frame tile differentiates,
// "read" = pc.read, the uploaded rect: it holds every receiver within reach of the core (the
// core of passes 1 and 2, whose outputs are stored read-local) and their windows:
//   0: rgba            readonly  vec4[layer_count * read pixels]
//   1: disparity       readonly  float[layer_count * read pixels]
//   2: receiver        readonly  vec4[layer_count * read pixels]  (pass 2: rel_x, alpha_x, V / sum D, h_x)
//   3: area_lut        readonly  float[area_count]
//   4: kernel          readonly  float[max(1, kernel_size^2)]
//   5: adj_cw          readonly  vec4[layer_count * read pixels]  (pass 1)
//   6: own             readonly  vec4[layer_count * read pixels]  (pass 2; the source's own entry only)
//   7: grad_rgba       writeonly vec4[layer_count * core pixels]
//   8: grad_disparity  writeonly float[layer_count * core pixels]
//   9: k_partial       writeonly float[layer_count * core pixels]
//  10: tile_reach      readonly  int[layer_count * tiles_x * tiles_y] whole image (pass 3, host:
//                                backward_cpu.rs `tile_reach_cpu`)
// Push constants: DrBokehPush (leaky_slope included).
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer, after pass 2
// (pass 3's tile_reach is uploaded with the inputs). The disk path
// (drbokeh_backward_source_disk.comp) has the same grid of 8x16 invocations of RUN = 2 sources each.
// Body and the taps it skips (exact zeros only): glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh_backward_source.glsl"
