// Real spherical harmonics, degrees 1..3, in the basis and sign convention of the reference 3DGS
// code (the coefficients in trained files assume it). Degree 0 is folded into the base colour.
// sh_coeff(g, j) comes from the fetch_*.glsl layout in use.
#if SH_DEGREE > 0
vec3 sh_view_terms(uint g, vec3 dir) {
    float x = dir.x, y = dir.y, z = dir.z;
    vec3 c = 0.4886025119029199 * (-y * sh_coeff(g, 0) + z * sh_coeff(g, 1) - x * sh_coeff(g, 2));
#if SH_DEGREE > 1
    float xx = x * x, yy = y * y, zz = z * z;
    c += 1.0925484305920792 * x * y * sh_coeff(g, 3)
       - 1.0925484305920792 * y * z * sh_coeff(g, 4)
       + 0.31539156525252005 * (2.0 * zz - xx - yy) * sh_coeff(g, 5)
       - 1.0925484305920792 * x * z * sh_coeff(g, 6)
       + 0.5462742152960396 * (xx - yy) * sh_coeff(g, 7);
#endif
#if SH_DEGREE > 2
    c += -0.5900435899266435 * y * (3.0 * xx - yy) * sh_coeff(g, 8)
       + 2.890611442640554 * x * y * z * sh_coeff(g, 9)
       - 0.4570457994644658 * y * (4.0 * zz - xx - yy) * sh_coeff(g, 10)
       + 0.3731763325901154 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * sh_coeff(g, 11)
       - 0.4570457994644658 * x * (4.0 * zz - xx - yy) * sh_coeff(g, 12)
       + 1.445305721320277 * z * (xx - yy) * sh_coeff(g, 13)
       - 0.5900435899266435 * x * (xx - 3.0 * yy) * sh_coeff(g, 14);
#endif
    return c;
}
#endif
