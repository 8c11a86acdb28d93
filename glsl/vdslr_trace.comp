// Virtual DSLR (Yang et al. 2016): per pixel, jittered lens samples traced in image space on
// the (focus-edited) relative disparity map; randomized search, symmetric fill, bleeding guard,
// Eq. 5 highlight weighting; mixed pixels at depth edges blend the traces at the nearer and the
// farther surface's depth. CPU reference: src/render/vdslr/mod.rs `Tracer` (same order).
//
// Bindings (set 0):
//   0: image     vec4[read.z * read.w]   premultiplied linear RGBA of the read rect
//   1: relative  float[read.z * read.w]  d - d_f(x, y), the edited disparity map
//   2: disparity float[read.z * read.w]  true disparity (bleeding guard: which pixel is farther)
//   3: samples   vec4[patterns * slots] (u, v, weight, 0), unit disk, aperture coordinates
//   4: edges     vec4[core.z * core.w]   (coverage, near, far, 0) of mixed edge pixels, else 0;
//                                        near, far: 3x3 neighbour numbers (`neighbour`)
//   5: result    vec4[core.z * core.w]
// Push constants: VdslrPush (src/render/vdslr/gpu.rs).
// Dispatch: (ceil(core.z / 8), ceil(core.w / 8), 1).
// Tiled (src/render/tiling.rs, glsl/common/tile.glsl): the dispatch covers `core`, sources
// are the `read` rect, results core-local; width and height are the full frame's.
// Sample sets are picked by frame position, and every search step's pixel (and a mixed edge
// pixel's 3x3 neighbours) lies within the halo (the ray's reach, VdslrTiling in
// src/render/vdslr/gpu.rs).
//
// `precise` keeps every position computation unfused (no FMA contraction), so the pixel each
// search reads is the one the CPU reference reads.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "image.glsl"
#include "tile.glsl"
#include "sampling.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "dispatch.glsl"

// Read at lane-varying addresses: uniform texel buffers (texelFetch), see Slot::Texels in
// src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer source;
layout(set = 0, binding = 1) uniform samplerBuffer relative;
layout(set = 0, binding = 2) uniform samplerBuffer disparity;
layout(std430, set = 0, binding = 3) readonly buffer Samples { vec4 samples[]; };
layout(set = 0, binding = 4) uniform samplerBuffer edges;
layout(std430, set = 0, binding = 5) writeonly buffer Result { vec4 result[]; };

layout(push_constant) uniform Push {
    int width;
    int height;
    int iterations;
    int slots;
    int patterns;
    int bleeding_guard;
    int highlight;
    int pad;
    float k;
    float s_max;
    float sigma;
    float white;
    ivec4 core;
    ivec4 read;
} pc;

struct Hit {
    int index;
    bool valid;
};

// The pixel being shaded and the depth it is traced at: its own relative (s) and true (d)
// disparity, or the farther surface's for a mixed edge pixel (CPU reference: `Centre`).
struct Centre {
    int index;
    float s;
    float d;
};

float disparity_at(int index, Centre at) {
    return index == at.index ? at.d : texelFetch(disparity, index).x;
}

int nearest_pixel(float x, int size) {
    return int(clamp(floor(x + 0.5), 0.0, float(size - 1)));
}

// The relaxed Eq. 4: pixel q of relative disparity s_q lies within half a pixel (per axis) of
// where the ray p + u s is at s = s_q.
bool hits(vec2 p, vec2 u, ivec2 q, float s_q) {
    precise float ex = float(q.x) - (p.x + u.x * s_q);
    precise float ey = float(q.y) - (p.y + u.y * s_q);
    return abs(ex) <= 0.5 && abs(ey) <= 0.5;
}

// Randomized intersection search along p + u s (u already scaled by K).
Hit search(vec2 p, vec2 u, Centre at) {
    int centre = at.index;
    float s_t = pc.s_max;
    int other = centre;
    for (int t = 0; t <= pc.iterations; ++t) {
        precise float px = p.x + u.x * s_t;
        precise float py = p.y + u.y * s_t;
        int qx = nearest_pixel(px, pc.width);
        int qy = nearest_pixel(py, pc.height);
        int index = rect_index(ivec2(qx, qy), pc.read);
        float s_q = index == centre ? at.s : texelFetch(relative, index).x;
        if (hits(p, u, ivec2(qx, qy), s_q)) {
            return Hit(index, true);
        }
        if (index != centre) {
            other = index;
        }
        s_t = s_q;
    }
    // Failed: the last pixel read other than the centre (CPU reference: `Tracer::search`).
    return Hit(other, false);
}

// Pixel number n (0..9, row by row, 4 the pixel itself) of the 3x3 neighbourhood of x, clamped
// at the frame (CPU reference: `neighbour`).
int neighbour(ivec2 x, int n) {
    int qx = min(max(x.x + n % 3 - 1, 0), pc.width - 1);
    int qy = min(max(x.y + n / 3 - 1, 0), pc.height - 1);
    return rect_index(ivec2(qx, qy), pc.read);
}

float highlight_weight(vec4 c) {
    if (pc.highlight == 0) {
        return 1.0;
    }
    float m = min(max(max(c.r, c.g), c.b), pc.white);
    return exp(-(m - pc.white) * (m - pc.white) / (2.0 * pc.sigma * pc.sigma));
}

// The pixel whose colour stands for the farther surface at a mixed pixel: of the neighbours
// beyond `midway`, the one whose colour differs most from the nearer neighbour's (first of the
// largest in neighbour order); the centre if none (CPU reference: `Tracer::farther_colour`).
int farther_colour(ivec2 x, int centre, int near, float midway) {
    vec3 near_colour = texelFetch(source, near).rgb;
    int best = centre;
    float best_distance = -1.0;
    for (int n = 0; n < 9; ++n) {
        int q = neighbour(x, n);
        if (n == 4 || q == centre || texelFetch(disparity, q).x > midway) {
            continue;
        }
        precise vec3 diff = texelFetch(source, q).rgb - near_colour;
        precise float distance = diff.r * diff.r + diff.g * diff.g + diff.b * diff.b;
        if (distance > best_distance) {
            best = q;
            best_distance = distance;
        }
    }
    return best;
}

// The pixel's lens samples first, first + step, ... traced with the centre at relative
// disparity s_c and true disparity d_c (CPU reference: `Tracer::trace`).
// `colour`: the pixel whose colour stands for the centre's surface (CPU reference: `Surface`).
vec4 trace(ivec2 x, float s_c, float d_c, int colour, int first, int step) {
    int centre = rect_index(x, pc.read);
    Centre at = Centre(centre, s_c, d_c);
    vec2 p = vec2(x);
    int base = int(pattern_index(uvec2(x), uint(pc.patterns))) * pc.slots;
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    for (int i = first; i < pc.slots; i += step) {
        vec4 s = samples[base + i];
        if (s.z <= 0.0) {
            continue;
        }
        precise vec2 u = vec2(s.x * pc.k, s.y * pc.k);
        Hit hit = search(p, u, at);
        bool centre_hit = hits(p, u, x, s_c);
        // Passes beside the centre's surface: keep the farther pixel, not the mirror (CPU
        // reference: `Tracer::shade`).
        bool beside = !centre_hit && disparity_at(hit.index, at) < d_c;
        if (!hit.valid && !beside) {
            Hit mirrored = search(p, -u, at);
            if (mirrored.valid) {
                hit = mirrored;
            }
        }
        // Guard as in the CPU reference: when the centre is a nearer hit of this ray.
        bool farther = disparity_at(hit.index, at) < d_c;
        bool guard = pc.bleeding_guard != 0 && farther && centre_hit;
        int index = guard ? centre : hit.index;
        vec4 c = texelFetch(source, index == centre ? colour : index);
        float w = s.z * highlight_weight(c);
        sum += w * c;
        weight += w;
    }
    return weight > 0.0 ? sum / weight : texelFetch(source, colour);
}

void main() {
    ivec2 local = ivec2(spread_global_invocation_id().xy);
    if (!inside(local, pc.core.zw)) {
        return;
    }
    ivec2 x = pc.core.xy + local;
    int centre = rect_index(x, pc.read);
    int out_index = rect_index(x, pc.core);
    // A mixed edge pixel: the traces at the nearer and the farther surface's depth over the
    // even and the odd sample slots, blended by coverage (CPU reference: `Tracer::shade`).
    vec4 edge = texelFetch(edges, out_index);
    if (edge.x > 0.0) {
        int near = neighbour(x, int(edge.y));
        int far = neighbour(x, int(edge.z));
        float d_near = texelFetch(disparity, near).x;
        float d_far = texelFetch(disparity, far).x;
        int far_colour = farther_colour(x, centre, near, 0.5 * (d_near + d_far));
        vec4 near_trace = trace(x, texelFetch(relative, near).x, d_near, centre, 0, 2);
        vec4 far_trace = trace(x, texelFetch(relative, far).x, d_far, far_colour, 1, 2);
        result[out_index] = edge.x * near_trace + (1.0 - edge.x) * far_trace;
    } else {
        result[out_index] = trace(x, texelFetch(relative, centre).x, texelFetch(disparity, centre).x, centre, 0, 1);
    }
}
