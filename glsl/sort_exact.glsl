// The CPU sort's float32 arithmetic, repeated bit for bit (see sort_common.glsl).

// The positive finite float next above / below ``r`` (r > 0, finite).
float next_up(float r) {
    return uintBitsToFloat(floatBitsToUint(r) + 1u);
}
float next_down(float r) {
    return uintBitsToFloat(floatBitsToUint(r) - 1u);
}

// The float32 ``s`` as a double, built from its bits: exact also for a subnormal ``s``,
// which a GPU converting floats may flush to zero.
double exact_double(float s) {
    uint bits = floatBitsToUint(s) & 0x7FFFFFFFu;
    uint exponent = bits >> 23u, mantissa = bits & 0x7FFFFFu;
    return exponent == 0u ? ldexp(double(mantissa), -149) : ldexp(double(mantissa | 0x800000u), int(exponent) - 150);
}

// sqrt(s) correctly rounded to float32, as numpy's (IEEE) square root, for s >= 0.
// A first guess from the double square root, then up to three steps of one ulp: r is the
// correctly rounded root exactly when s lies between the squares of the midpoints
// around r. Twice a midpoint, r + its neighbour, has 25 significant bits, its square
// 50: both exact in double, as is 4 s, so every comparison is exact. A tie cannot
// occur: the square of a midpoint has a bit below the last bit of any float near it.
float sqrt_rn(float s) {
    uint bits = floatBitsToUint(s);
    if (bits == 0u || bits >= 0x7F800000u) return s;  // +0, +inf, NaN (and negatives: never asked)
    double four_s = 4.0LF * exact_double(s);
    float r = float(sqrt(exact_double(s)));
    for (int step = 0; step < 3; ++step) {
        double up = double(r) + double(next_up(r));
        double down = double(r) + double(next_down(r));
        if (four_s > up * up) r = next_up(r);
        else if (four_s < down * down) r = next_down(r);
    }
    return r;
}

// Row ``axis`` of camera space: ((R_i0 x + R_i1 y) + R_i2 z) + t_i, every product and
// sum rounded to float32 on its own (keys.camera_space). ``row``: (R_i0, R_i1, R_i2, t_i).
float camera_axis(vec3 p, vec4 row) {
    precise float x = p.x * row.x;
    precise float y = p.y * row.y;
    precise float z = p.z * row.z;
    precise float sum = x + y;
    sum = sum + z;
    sum = sum + row.w;
    return sum;
}

// |p - C| as keys.distances computes it: (dx^2 + dy^2) + dz^2, then the root.
float centre_distance(vec3 p, vec3 centre) {
    precise float dx = p.x - centre.x;
    precise float dy = p.y - centre.y;
    precise float dz = p.z - centre.z;
    precise float xx = dx * dx;
    precise float yy = dy * dy;
    precise float zz = dz * dz;
    precise float sum = xx + yy;
    sum = sum + zz;
    return sqrt_rn(sum);
}
