// Per-Gaussian attributes from the packed layout (dofview/packing.py): 32 B core + half SH.
// Colour coefficients are stored divided by COLOUR_SCALE (a power of two, #defined by the loader).
layout(std430, binding = 0) readonly buffer Core { uint core[]; };
#if SH_DEGREE > 0
layout(std430, binding = 2) readonly buffer ShRest { uint sh_words[]; };
#endif

vec3 load_mean(uint g) {
    uint b = g * 8u;
    return vec3(uintBitsToFloat(core[b]), uintBitsToFloat(core[b + 1u]), uintBitsToFloat(core[b + 2u]));
}

vec3 load_scale(uint g) {
    vec2 xy = unpackHalf2x16(core[g * 8u + 3u]);
    return vec3(xy, unpackHalf2x16(core[g * 8u + 4u]).x);
}

vec3 load_base(uint g) {
    return vec3(unpackHalf2x16(core[g * 8u + 4u]).y, unpackHalf2x16(core[g * 8u + 5u])) * COLOUR_SCALE;
}

float load_opacity(uint g) {
    return float(core[g * 8u + 7u] >> 18u) / 16383.0;
}

vec4 load_quat(uint g) {  // (w, x, y, z)
    uint w6 = core[g * 8u + 6u];
    uint w7 = core[g * 8u + 7u];
    vec3 rest = vec3(unpackSnorm2x16(w6), unpackSnorm2x16(w7).x) * 0.7071067811865476;
    uint largest = (w7 >> 16u) & 3u;
    float big = sqrt(max(1.0 - dot(rest, rest), 0.0));
    vec4 q;
    if (largest == 0u) q = vec4(big, rest);
    else if (largest == 1u) q = vec4(rest.x, big, rest.y, rest.z);
    else if (largest == 2u) q = vec4(rest.x, rest.y, big, rest.z);
    else q = vec4(rest, big);
    return normalize(q);
}

#if SH_DEGREE > 0
vec3 sh_coeff(uint g, int j) {
    uint h = g * uint(SH_REST * 3) + uint(j * 3);
    float c[3];
    for (int i = 0; i < 3; ++i) {
        uint k = h + uint(i);
        vec2 pair = unpackHalf2x16(sh_words[k >> 1u]);
        c[i] = (k & 1u) == 0u ? pair.x : pair.y;
    }
    return vec3(c[0], c[1], c[2]) * COLOUR_SCALE;
}
#endif
