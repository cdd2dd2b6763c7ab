// Per-Gaussian attributes from the float32 layout (dofview/packing.py:full_core).
layout(std430, binding = 0) readonly buffer Core { float core[]; };
#if SH_DEGREE > 0
layout(std430, binding = 2) readonly buffer ShRest { float sh_rest[]; };
#endif

vec3 load_mean(uint g) { uint b = g * 14u; return vec3(core[b], core[b + 1u], core[b + 2u]); }
float load_opacity(uint g) { return core[g * 14u + 3u]; }
vec4 load_quat(uint g) { uint b = g * 14u + 4u; return vec4(core[b], core[b + 1u], core[b + 2u], core[b + 3u]); }
vec3 load_scale(uint g) { uint b = g * 14u + 8u; return vec3(core[b], core[b + 1u], core[b + 2u]); }
vec3 load_base(uint g) { uint b = g * 14u + 11u; return vec3(core[b], core[b + 1u], core[b + 2u]); }

#if SH_DEGREE > 0
vec3 sh_coeff(uint g, int j) {
    uint o = g * uint(SH_REST * 3) + uint(j * 3);
    return vec3(sh_rest[o], sh_rest[o + 1u], sh_rest[o + 2u]);
}
#endif
