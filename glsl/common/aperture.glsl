// Aperture shapes: the lens term K(y, x). Mirrors src/camera/aperture.rs (`polygon_gauge`,
// `Aperture::gauge`, `Aperture::to_aperture_coords`, `KernelImage::sample`); the f64 mirror
// used by the CPU reference is src/render/drbokeh/math.rs.
//
// The aperture arrives as `Aperture::gpu_params`: vec4(shape, rotation (rad), parameter,
// kernel (1 = sample the kernel buffer)); shape 0 = disk (or kernel image), 1 = ellipse
// (parameter = squeeze), 2 = ring (parameter = inner radius), >= 3 = polygon of that many
// blades (parameter = roundness), -1 = cat's-eye (vec4(-1, a, 0): the unit disks at +-a).
//
// A shader that calls `aperture_kernel_sample` must define
//     float aperture_kernel_texel(int index);
// returning element `index` of its kernel buffer (row-major, size x size): GLSL cannot pass
// buffers to functions.
#ifndef LENSBLUR_APERTURE_GLSL
#define LENSBLUR_APERTURE_GLSL

const float APERTURE_PI = 3.14159265358979323846;

float aperture_kernel_texel(int index);

// Near sources (positive relative disparity) project the aperture mirrored through its centre.
vec2 aperture_coords(vec2 offset, float relative_disparity) {
    return relative_disparity > 0.0 ? -offset : offset;
}

// Gauge of a regular n-gon inscribed in the unit circle, blended toward the disk by roundness.
// floor(x + 0.5) stands for Rust's round(): they differ only at exact half sectors, where the
// folded angle is +-sector/2 and cos gives the same value.
float aperture_polygon_gauge(vec2 p, float n, float rotation, float roundness) {
    float len = length(p);
    if (len == 0.0) {
        return 0.0; // atan(0, 0) is undefined in GLSL
    }
    float sector = 2.0 * APERTURE_PI / n;
    float theta = atan(p.y, p.x) - rotation;
    float folded = theta - sector * floor(theta / sector + 0.5);
    float poly = len * cos(folded) / cos(APERTURE_PI / n);
    return poly + (len - poly) * roundness;
}

// Gauge of the ellipse with semi-axes 1 (at `rotation` from +u toward +v) and 1 / squeeze.
float aperture_ellipse_gauge(vec2 p, float rotation, float squeeze) {
    float c = cos(rotation);
    float s = sin(rotation);
    return length(vec2(p.x * c + p.y * s, (p.y * c - p.x * s) * squeeze));
}

// Gauge of the cat's-eye, the intersection of the unit disks at a and -a (`cats_eye_gauge` in
// src/camera/aperture.rs).
float aperture_cats_eye_gauge(vec2 p, vec2 a) {
    float k = 1.0 - dot(a, a);
    float q = abs(dot(p, a));
    return (q + sqrt(q * q + k * dot(p, p))) / k;
}

// The aperture's gauge of an offset in aperture coordinates (Euclidean for disks, rings and
// kernels).
float aperture_gauge(vec2 p, vec4 aperture) {
    if (aperture.x < -0.5) {
        return aperture_cats_eye_gauge(p, aperture.yz);
    }
    if (aperture.x < 0.5) {
        return length(p);
    }
    if (aperture.x < 1.5) {
        return aperture_ellipse_gauge(p, aperture.y, aperture.z);
    }
    if (aperture.x < 2.5) {
        return length(p);
    }
    return aperture_polygon_gauge(p, aperture.x, aperture.y, aperture.z);
}

float aperture_kernel_at(float x, float y, int size) {
    float n = float(size);
    if (x < 0.0 || y < 0.0 || x >= n || y >= n) {
        return 0.0;
    }
    return aperture_kernel_texel(int(y) * size + int(x));
}

// Bilinear sample of the size x size kernel image at uv in [-1, 1]^2; zero outside.
float aperture_kernel_sample(vec2 uv, int size) {
    float n = float(size);
    float fx = (uv.x * 0.5 + 0.5) * n - 0.5;
    float fy = (uv.y * 0.5 + 0.5) * n - 0.5;
    if (!(fx > -1.0 && fy > -1.0 && fx < n && fy < n)) {
        return 0.0;
    }
    float x0 = floor(fx);
    float y0 = floor(fy);
    float tx = fx - x0;
    float ty = fy - y0;
    float top = aperture_kernel_at(x0, y0, size) * (1.0 - tx) + aperture_kernel_at(x0 + 1.0, y0, size) * tx;
    float bottom = aperture_kernel_at(x0, y0 + 1.0, size) * (1.0 - tx) + aperture_kernel_at(x0 + 1.0, y0 + 1.0, size) * tx;
    return top * (1.0 - ty) + bottom * ty;
}

// CoC radii (pixels) over which kernel-image weights fade in (`KERNEL_FADE_PX`).
const float APERTURE_KERNEL_FADE_START_PX = 0.5;
const float APERTURE_KERNEL_FADE_END_PX = 1.5;

bool aperture_is_ring(vec4 aperture) {
    return aperture.x > 1.5 && aperture.x < 2.5;
}

// The ring's weight at distance g from the centre of a CoC of radius r: an obstruction of
// radius inner * r with the rim's one-pixel Hermite edge, faded in like kernel images.
// Mirrors `ring_weight` in src/camera/aperture.rs.
float aperture_ring_weight(float g, float r, float inner) {
    float blend = smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r);
    return 1.0 - blend * (1.0 - smoothstep(0.0, 1.0, g - (inner * r - 0.5)));
}

// Kernel-image weight of the offset p (aperture coordinates, pixels) from a source whose CoC
// has radius r: the image spans the soft disk of radius r + 1/2 and fades in over 0.5..1.5 px
// of CoC (a sub-pixel kernel integrates to a point). The ring's weight; 1 without a kernel
// (disks, polygons, ellipses). Mirrors `Aperture::kernel_weight`.
float aperture_kernel_weight(vec2 p, float r, vec4 aperture, int kernel_size) {
    if (aperture_is_ring(aperture)) {
        return aperture_ring_weight(length(p), r, aperture.z);
    }
    if (aperture.w < 0.5 || kernel_size == 0) {
        return 1.0;
    }
    float sample_weight = aperture_kernel_sample(p / (r + 0.5), kernel_size);
    float blend = smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r);
    return 1.0 + (sample_weight - 1.0) * blend;
}

#endif
