// The filter compute shader of HPG17 §4.1: one thread group of 256 threads turns one 32x24
// block of a 4x MSAA shadow map into filtered moments, entirely in groupshared memory.
//
//   resolve     each thread loads all samples of a texel of the 40x32 input block (the
//               output block and a guard band of 4 on every side), averages
//               b(z) = (z, z^2, z^3, z^4) and stores the four moments;
//   horizontal  the 9-tap Gaussian (sigma 2.4) along the rows, in registers;
//   vertical    the same along the columns;
//   readout     each thread reads three complete moment vectors of the output block.
//
// HLSL (glslang's front end; DXC-compatible syntax), float32. Part of moments_ref; include it
// and write the texels in your own entry point (hpg17_filter_nlq64.hlsl and its siblings do).
// The access pattern of every phase is the one of moments_ref/gpu/banks.py, whose
// bank-conflict count `moments-ref conformance` checks against this code by running it (the
// lines tagged mr:shared-load / mr:shared-store are traced); the arithmetic is the one of
// moments_ref/gpu/onchip.py.
//
// Bindings (docs/ports.md, "Kernels"): t0 the multisampled depth texture (window depth d in
// [0, 1], z = 2 d - 1), u1 your output, b2 the constant buffer Params.

#ifndef MOMENTS_REF_HPG17_FILTER_HLSL
#define MOMENTS_REF_HPG17_FILTER_HLSL

Texture2DMS<float> depth : register(t0);

cbuffer Params : register(b2)
{
    uint4 size;          // map width, height, MSAA samples, light views
    int4 origin;         // xy: texel of thread group (0, 0) of this dispatch; zw: views (VWSS)
    uint4 count;         // x: points (VWSS)
    float4 bias;         // x: alpha of the moment bias (HPG17 §3.2)
    float4 bias_target;  // b*
};

static const uint HPG17_BLOCK_W = 32;   // output block
static const uint HPG17_BLOCK_H = 24;
static const int HPG17_GUARD = 4;       // half the 9-tap filter
static const uint HPG17_MOMENT_STRIDE = 40 * 32 + 7;

groupshared float hpg17_lds[4 * HPG17_MOMENT_STRIDE];

// The 9-tap Gaussian, sigma = 2.4 texels, normalized (moments_ref.gpu.filtering.gaussian_weights
// rounded to float32).
static const float HPG17_WEIGHTS[9] = { 0.044044435, 0.08086959, 0.12481912, 0.16194914, 0.17663543,
                                        0.16194914, 0.12481912, 0.08086959, 0.044044435 };

// HPG17 §4.1 "Memory layout": moment b_j (j = 1..4) of block cell (x, y) lives at
//     (40*32 + 7)(j - 1) + 40 y + floor(y / 4) + (x < 20 ? 2 x : 2 x - 39):
// the left 20 cells of a row on even words, the right 20 on odd words, one padding word
// after every 4 rows; no phase has a bank conflict.
uint hpg17_index(uint j, uint x, uint y)
{
    return HPG17_MOMENT_STRIDE * (j - 1) + 40 * y + y / 4 + (x < 20 ? 2 * x : 2 * x - 39);
}

// Every shared-memory load goes through this function (the harness traces it) ...
float hpg17_load(uint a) { return hpg17_lds[a]; }            // mr:shared-load
// ... and every store through this one.
void hpg17_store(uint a, float v) { hpg17_lds[a] = v; }      // mr:shared-store

// Resolve (Figure 6a): in round r warp w takes column x = 8 r + w, lane l row y = l; the
// texel is clamped to the map (the guard band at the border), its samples averaged.
void hpg17_resolve(int2 in_origin, uint warp, uint lane)
{
    int2 last = int2(size.xy) - 1;
    for (uint r = 0; r < 5; ++r) {
        uint x = 8 * r + warp;
        uint y = lane;
        int2 t = clamp(in_origin + int2(x, y), int2(0, 0), last);
        float4 acc = float4(0.0, 0.0, 0.0, 0.0);
        for (int s = 0; s < int(size.z); ++s) {
            float z = 2.0 * depth.Load(t, s) - 1.0;   // window depth -> [-1, 1]
            float z2 = z * z;
            acc += float4(z, z2, z2 * z, z2 * z2);
        }
        acc /= float(size.z);
        for (uint j = 1; j <= 4; ++j)
            hpg17_store(hpg17_index(j, x, y), acc[j - 1]);
    }
}

// Horizontal pass (Figure 6b): warp w blurs moment w mod 4 + 1 in half h = w div 4; lane l
// owns row l, loads the 24 cells 16 h .. 16 h + 23 and writes its 16 results to the
// columns no warp reads (left 0..15, right 24..39).
void hpg17_horizontal(uint warp, uint lane)
{
    uint j = warp % 4 + 1;
    uint h = warp / 4;
    float v[24];
    for (uint k = 0; k < 24; ++k)
        v[k] = hpg17_load(hpg17_index(j, 16 * h + k, lane));
    for (uint k2 = 0; k2 < 16; ++k2) {
        float acc = HPG17_WEIGHTS[0] * v[k2];
        for (uint t = 1; t < 9; ++t)
            acc += HPG17_WEIGHTS[t] * v[k2 + t];
        hpg17_store(hpg17_index(j, 24 * h + k2, lane), acc);
    }
}

// Vertical pass (Figure 6c), loads: on the strip of columns 24 h .. 24 h + 15, lane l takes
// column l mod 16 and rows 0..19 (l < 16) or 12..31.
void hpg17_vertical_load(uint warp, uint lane, out float v[20])
{
    uint j = warp % 4 + 1;
    uint x = 24 * (warp / 4) + lane % 16;
    uint y0 = 12 * (lane / 16);
    for (uint k = 0; k < 20; ++k)
        v[k] = hpg17_load(hpg17_index(j, x, y0 + k));
}

// Vertical pass, stores: the 12 results in place, rows 4..15 (upper) or 16..27 (lower).
void hpg17_vertical_store(uint warp, uint lane, float v[20])
{
    uint j = warp % 4 + 1;
    uint x = 24 * (warp / 4) + lane % 16;
    uint y0 = 4 + 12 * (lane / 16);
    for (uint k = 0; k < 12; ++k) {
        float acc = HPG17_WEIGHTS[0] * v[k];
        for (uint t = 1; t < 9; ++t)
            acc += HPG17_WEIGHTS[t] * v[k + t];
        hpg17_store(hpg17_index(j, x, y0 + k), acc);
    }
}

// Readout (Figure 6d): warp w reads output rows w, w + 8, w + 16; lane l is output column l,
// at cell l (l < 16) or l + 8, row + 4.
float4 hpg17_readout(uint i, uint warp, uint lane)
{
    uint x = lane < 16 ? lane : lane + 8;
    uint y = warp + 8 * i + HPG17_GUARD;
    float4 b;
    for (uint j = 1; j <= 4; ++j)
        b[j - 1] = hpg17_load(hpg17_index(j, x, y));
    return b;
}

// The whole block program for thread gi of group gid. Afterwards the thread holds the
// filtered moments b[i] of the texels texel[i] (i = 0..2); texels outside the map must not
// be written.
void hpg17_filter(uint3 gid, uint gi, out float4 b[3], out int2 texel[3])
{
    uint warp = gi / 32;
    uint lane = gi % 32;
    int2 out_origin = origin.xy + int2(gid.xy) * int2(HPG17_BLOCK_W, HPG17_BLOCK_H);
    hpg17_resolve(out_origin - HPG17_GUARD, warp, lane);
    GroupMemoryBarrierWithGroupSync();
    hpg17_horizontal(warp, lane);
    GroupMemoryBarrierWithGroupSync();
    float column[20];
    hpg17_vertical_load(warp, lane, column);
    // The upper lanes overwrite rows 12..15, which the lower lanes read: all loads first
    // (one warp of 32 does this in lockstep; narrower hardware needs the barrier, §4.1).
    GroupMemoryBarrierWithGroupSync();
    hpg17_vertical_store(warp, lane, column);
    GroupMemoryBarrierWithGroupSync();
    for (uint i = 0; i < 3; ++i) {
        b[i] = hpg17_readout(i, warp, lane);
        texel[i] = out_origin + int2(lane, warp + 8 * i);
    }
}

#endif // MOMENTS_REF_HPG17_FILTER_HLSL
