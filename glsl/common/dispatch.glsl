// Workgroup order for CPU Vulkan drivers. lavapipe (Mesa's CPU Vulkan, what CI and machines
// without a GPU run) hands each of its threads one contiguous run of a dispatch's workgroups in
// row-major order, that is a band of rows per thread. Defocus cost is clustered where the
// blurred content is, so one thread can get most of a pass (measured: 3.3x the other thread's
// work on a 1024^2 frame with five layers of discs over a sharp background). Heavy passes
// therefore let workgroup row j work on row j * s mod n (n rows, s coprime to n, near n / phi):
// a bijection, so every pixel is still written exactly once with the same value, and every
// contiguous run of workgroups covers rows spread over the whole frame. GPUs schedule
// workgroups dynamically and do not care.
#ifndef LENSBLUR_DISPATCH_GLSL
#define LENSBLUR_DISPATCH_GLSL

uint dispatch_gcd(uint a, uint b) {
    while (b != 0u) {
        uint t = a % b;
        a = b;
        b = t;
    }
    return a;
}

// The workgroup row that workgroup row `row` of `rows` works on. rows <= 65535 (the dispatch
// limit), so row * s does not overflow.
uint spread_workgroup_row(uint row, uint rows) {
    uint s = max(uint(float(rows) * 0.618034), 1u);
    while (dispatch_gcd(s, rows) != 1u) {
        s += 1u;
    }
    return (row * s) % rows;
}

// gl_GlobalInvocationID with the workgroup rows spread as above; x and z are unchanged.
uvec3 spread_global_invocation_id() {
    uint row = spread_workgroup_row(gl_WorkGroupID.y, gl_NumWorkGroups.y);
    return uvec3(gl_GlobalInvocationID.x, row * gl_WorkGroupSize.y + gl_LocalInvocationID.y, gl_GlobalInvocationID.z);
}

#endif
