// The filter compute shader of HPG17 §4.1: one work group of 256 threads turns one 32x24
// block of a 4x MSAA shadow map into filtered moments, entirely in shared memory.
//
//   resolve     each thread loads all samples of a texel of the 40x32 input block (the
//               output block and a guard band of 4 on every side), averages
//               b(z) = (z, z^2, z^3, z^4) and stores the four moments;
//   horizontal  the 9-tap Gaussian (sigma 2.4) along the rows, in registers;
//   vertical    the same along the columns;
//   readout     each thread reads three complete moment vectors of the output block.
//
// GLSL 4.30, float32. Part of moments_ref; include it and write the texels in your own
// main() (hpg17_filter_nlq64.glsl and its siblings do). The access pattern of every
// phase (which thread touches which cell) is the one of moments_ref/gpu/banks.py, whose
// bank-conflict count `moments-ref conformance` checks against this code by running it
// (the lines tagged mr:shared-load / mr:shared-store are traced). The arithmetic is the
// one of moments_ref/gpu/onchip.py (the NumPy emulation of this shader).
//
// Bindings (docs/ports.md, "Kernels"): set 0, binding 0 the multisampled depth texture
// (window depth d in [0, 1], z = 2 d - 1), binding 1 your output, binding 2 the uniform
// block Params.

#ifndef MOMENTS_REF_HPG17_FILTER_GLSL
#define MOMENTS_REF_HPG17_FILTER_GLSL

layout(binding = 0) uniform sampler2DMS depth;

layout(std140, binding = 2) uniform Params {
    uvec4 size;          // map width, height, MSAA samples, light views
    ivec4 origin;        // xy: texel of work group (0, 0) of this dispatch; zw: views (VWSS)
    uvec4 count;         // x: points (VWSS)
    vec4 bias;           // x: alpha of the moment bias (HPG17 §3.2)
    vec4 bias_target;    // b*
} params;

const uint HPG17_BLOCK_W = 32u;   // output block
const uint HPG17_BLOCK_H = 24u;
const int HPG17_GUARD = 4;        // half the 9-tap filter
const uint HPG17_MOMENT_STRIDE = 40u * 32u + 7u;

shared float hpg17_lds[4u * HPG17_MOMENT_STRIDE];

// The 9-tap Gaussian, sigma = 2.4 texels, normalized (moments_ref.gpu.filtering.gaussian_weights
// rounded to float32).
const float HPG17_WEIGHTS[9] = float[9](0.044044435, 0.08086959, 0.12481912, 0.16194914, 0.17663543,
                                        0.16194914, 0.12481912, 0.08086959, 0.044044435);

// HPG17 §4.1 "Memory layout": moment b_j (j = 1..4) of block cell (x, y) lives at
//     (40*32 + 7)(j - 1) + 40 y + floor(y / 4) + (x < 20 ? 2 x : 2 x - 39):
// the left 20 cells of a row on even words, the right 20 on odd words, one padding word
// after every 4 rows; no phase has a bank conflict.
uint hpg17_index(uint j, uint x, uint y)
{
    return HPG17_MOMENT_STRIDE * (j - 1u) + 40u * y + y / 4u + (x < 20u ? 2u * x : 2u * x - 39u);
}

float hpg17_load(uint a) { return hpg17_lds[a]; }            // mr:shared-load
void hpg17_store(uint a, float v) { hpg17_lds[a] = v; }      // mr:shared-store

// Resolve (Figure 6a): in round r warp w takes column x = 8 r + w, lane l row y = l; the
// texel is clamped to the map (the guard band at the border), its samples averaged.
void hpg17_resolve(ivec2 in_origin, uint warp, uint lane)
{
    ivec2 last = ivec2(params.size.xy) - 1;
    for (uint r = 0u; r < 5u; ++r) {
        uint x = 8u * r + warp;
        uint y = lane;
        ivec2 t = clamp(in_origin + ivec2(x, y), ivec2(0), last);
        vec4 acc = vec4(0.0);
        for (int s = 0; s < int(params.size.z); ++s) {
            float z = 2.0 * texelFetch(depth, t, s).r - 1.0;   // window depth -> [-1, 1]
            float z2 = z * z;
            acc += vec4(z, z2, z2 * z, z2 * z2);
        }
        acc /= float(params.size.z);
        for (uint j = 1u; j <= 4u; ++j)
            hpg17_store(hpg17_index(j, x, y), acc[j - 1u]);
    }
}

// Horizontal pass (Figure 6b): warp w blurs moment w mod 4 + 1 in half h = w div 4; lane l
// owns row l, loads the 24 cells 16 h .. 16 h + 23 and writes its 16 results to the
// columns no warp reads (left 0..15, right 24..39).
void hpg17_horizontal(uint warp, uint lane)
{
    uint j = warp % 4u + 1u;
    uint h = warp / 4u;
    float v[24];
    for (uint k = 0u; k < 24u; ++k)
        v[k] = hpg17_load(hpg17_index(j, 16u * h + k, lane));
    for (uint k = 0u; k < 16u; ++k) {
        float acc = HPG17_WEIGHTS[0] * v[k];
        for (uint t = 1u; t < 9u; ++t)
            acc += HPG17_WEIGHTS[t] * v[k + t];
        hpg17_store(hpg17_index(j, 24u * h + k, lane), acc);
    }
}

// Vertical pass (Figure 6c), loads: on the strip of columns 24 h .. 24 h + 15, lane l takes
// column l mod 16 and rows 0..19 (l < 16) or 12..31.
void hpg17_vertical_load(uint warp, uint lane, out float v[20])
{
    uint j = warp % 4u + 1u;
    uint x = 24u * (warp / 4u) + lane % 16u;
    uint y0 = 12u * (lane / 16u);
    for (uint k = 0u; k < 20u; ++k)
        v[k] = hpg17_load(hpg17_index(j, x, y0 + k));
}

// Vertical pass, stores: the 12 results in place, rows 4..15 (upper) or 16..27 (lower).
void hpg17_vertical_store(uint warp, uint lane, float v[20])
{
    uint j = warp % 4u + 1u;
    uint x = 24u * (warp / 4u) + lane % 16u;
    uint y0 = 4u + 12u * (lane / 16u);
    for (uint k = 0u; k < 12u; ++k) {
        float acc = HPG17_WEIGHTS[0] * v[k];
        for (uint t = 1u; t < 9u; ++t)
            acc += HPG17_WEIGHTS[t] * v[k + t];
        hpg17_store(hpg17_index(j, x, y0 + k), acc);
    }
}

// Readout (Figure 6d): warp w reads output rows w, w + 8, w + 16; lane l is output column l,
// at cell l (l < 16) or l + 8, row + 4.
vec4 hpg17_readout(uint i, uint warp, uint lane)
{
    uint x = lane < 16u ? lane : lane + 8u;
    uint y = warp + 8u * i + uint(HPG17_GUARD);
    vec4 b;
    for (uint j = 1u; j <= 4u; ++j)
        b[j - 1u] = hpg17_load(hpg17_index(j, x, y));
    return b;
}

// The whole block program. Afterwards thread (warp, lane) holds the filtered moments b[i]
// of the texels texel[i] (i = 0..2); texels outside the map must not be written.
void hpg17_filter(out vec4 b[3], out ivec2 texel[3])
{
    uint warp = gl_LocalInvocationIndex / 32u;
    uint lane = gl_LocalInvocationIndex % 32u;
    ivec2 out_origin = params.origin.xy + ivec2(gl_WorkGroupID.xy) * ivec2(HPG17_BLOCK_W, HPG17_BLOCK_H);
    hpg17_resolve(out_origin - HPG17_GUARD, warp, lane);
    memoryBarrierShared();
    barrier();
    hpg17_horizontal(warp, lane);
    memoryBarrierShared();
    barrier();
    float column[20];
    hpg17_vertical_load(warp, lane, column);
    // The upper lanes overwrite rows 12..15, which the lower lanes read: all loads first
    // (one warp of 32 does this in lockstep; narrower hardware needs the barrier, §4.1).
    barrier();
    hpg17_vertical_store(warp, lane, column);
    memoryBarrierShared();
    barrier();
    for (uint i = 0u; i < 3u; ++i) {
        b[i] = hpg17_readout(i, warp, lane);
        texel[i] = out_origin + ivec2(lane, warp + 8u * i);
    }
}

#endif // MOMENTS_REF_HPG17_FILTER_GLSL
