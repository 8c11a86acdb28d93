// Interior row spans of a disk and their sums from global 16-px block sums, shared by the
// layer pass's disk path (glsl/common/drbokeh_layer.glsl) and the backward's passes 2 and 4 on
// the disk (glsl/common/drbokeh_backward_own.glsl, drbokeh_backward_source.glsl): inside a
// disk of support t, where a tap's Hermite steps are exactly 1, a row's taps add one value
// each, so a row costs a span sum instead of one evaluation per tap.
#ifndef LENSBLUR_SPANS_GLSL
#define LENSBLUR_SPANS_GLSL

// `support` (a Hermite step's argument is support - g) less a margin far above f32 rounding:
// where the result - g >= 1 the step is exactly 1, however the compiler orders the adds of
// the taps' arguments.
float drbokeh_interior_bound(float support) {
    return support - support * (1.0 / 65536.0);
}

// An m in [-1, half_width] with t - g(m, oy) >= 1, g = sqrt(m^2 + oy^2) as the taps compute
// their Euclidean gauge: every column |o| <= m of the row is then interior (g grows with |o|).
// The largest such m or one less: the estimate is off by a rounding at most, and only a too
// large one is settled with the exact test (a column short costs one full tap, and m stays a
// function of t and oy alone, so of global positions).
int interior_half_width_disk(float t, float oy2, int half_width) {
    float room = max((t - 1.0) * (t - 1.0) - oy2, 0.0);
    int m = int(min(sqrt(room), float(half_width)));
    while (m >= 0 && t - sqrt(float(m * m) + oy2) < 1.0) {
        m -= 1;
    }
    return m;
}

// Defines `TYPE NAME(int base, int a, int b)`: the sum of a per-pixel value over global
// columns [a, b] of one read row (`base` + x = read index of global column x), where AT(i) is
// the value at read index i and PREFIX(i) / SUFFIX(i) its sums within i's global 16-px block
// from the block's first column to i and from i to its last (glsl/drbokeh_layer_blocks.comp).
// Within one block the columns left to right; else the suffix of a's block from a, the totals
// of the whole blocks between (left to right), then the prefix of b's block up to b. Which
// values enter depends on a and b only, and each is a function of global positions: the same
// bits for every read rect. Only block parts inside [a, b] (so inside the read rect) are read.
#define DRBOKEH_DEFINE_SPAN_SUM(TYPE, NAME, AT, PREFIX, SUFFIX)          \
    TYPE NAME(int base, int a, int b) {                                  \
        int block_a = a / DRBOKEH_TILE;                                  \
        int block_b = b / DRBOKEH_TILE;                                  \
        if (block_a == block_b) {                                        \
            if (a == block_a * DRBOKEH_TILE) {                           \
                return PREFIX(base + b);                                 \
            }                                                            \
            TYPE sum = TYPE(0.0);                                        \
            for (int x = a; x <= b; ++x) {                               \
                sum += AT(base + x);                                     \
            }                                                            \
            return sum;                                                  \
        }                                                                \
        TYPE sum = SUFFIX(base + a);                                     \
        for (int block = block_a + 1; block < block_b; ++block) {        \
            sum += SUFFIX(base + block * DRBOKEH_TILE);                  \
        }                                                                \
        return sum + PREFIX(base + b);                                   \
    }


// PREFIX and SUFFIX of the block sums' layout (glsl/common/drbokeh_blocks.glsl): a vec4 in
// block_prefix / block_suffix, a float in block_alpha (prefix, suffix), wherever a shader
// binds them under those names.
#define DRBOKEH_BLOCK_PREFIX(i) texelFetch(block_prefix, i)
#define DRBOKEH_BLOCK_SUFFIX(i) texelFetch(block_suffix, i)
#define DRBOKEH_BLOCK_SCALAR_PREFIX(i) texelFetch(block_alpha, i).x
#define DRBOKEH_BLOCK_SCALAR_SUFFIX(i) texelFetch(block_alpha, i).y

#endif
