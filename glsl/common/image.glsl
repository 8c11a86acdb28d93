// Shared helpers for RGBA float images stored as std430 vec4 arrays, row-major.
#ifndef LENSBLUR_IMAGE_GLSL
#define LENSBLUR_IMAGE_GLSL

// True when (x, y) lies inside a width x height image.
bool inside(ivec2 p, ivec2 size) {
    return p.x >= 0 && p.y >= 0 && p.x < size.x && p.y < size.y;
}

#endif
