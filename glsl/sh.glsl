// Real SH up to degree SH_DEGREE, INRIA order and constants (maths page, section 2).
// coeff(k) returns the RGB coefficient k of the current gaussian. SH_DEGREE is a
// literal in specialised variants (the bands above it compile away) and a uniform in
// the general one (see features.glsl).
vec3 sh_color(vec3 dir) {
    vec3 result = 0.28209479177387814 * coeff(0);
    if (SH_DEGREE >= 1) {
        float x = dir.x, y = dir.y, z = dir.z;
        result += 0.4886025119029199 * (-y * coeff(1) + z * coeff(2) - x * coeff(3));
        if (SH_DEGREE >= 2) {
            float xx = x * x, yy = y * y, zz = z * z;
            result += 1.0925484305920792 * x * y * coeff(4)
                    - 1.0925484305920792 * y * z * coeff(5)
                    + 0.31539156525252005 * (2.0 * zz - xx - yy) * coeff(6)
                    - 1.0925484305920792 * x * z * coeff(7)
                    + 0.5462742152960396 * (xx - yy) * coeff(8);
            if (SH_DEGREE >= 3) {
                result += -0.5900435899266435 * y * (3.0 * xx - yy) * coeff(9)
                        + 2.890611442640554 * x * y * z * coeff(10)
                        - 0.4570457994644658 * y * (4.0 * zz - xx - yy) * coeff(11)
                        + 0.3731763325901154 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * coeff(12)
                        - 0.4570457994644658 * x * (4.0 * zz - xx - yy) * coeff(13)
                        + 1.445305721320277 * z * (xx - yy) * coeff(14)
                        - 0.5900435899266435 * x * (xx - 3.0 * yy) * coeff(15);
            }
        }
    }
    return max(result + 0.5, 0.0);
}
