// An exclusive prefix sum over the invocations of a workgroup, in invocation order
// (Hillis-Steele, log2(WORKGROUP) steps over two shared rows). No subgroup operations
// (core GL 4.3). Every invocation must call it, from uniform control flow.
//
// Not a raking scan (a few invocations summing runs serially, fewer barriers): llvmpipe
// runs a branch that only some invocations take for all of them, masked, so the serial
// runs cost every invocation; they made the whole sort twice as slow there.

shared uint s_scan[2u * uint(WORKGROUP)];

// The sum of ``value`` over the invocations before this one; ``total`` the sum over all.
uint workgroup_exclusive_scan(uint value, out uint total) {
    uint t = gl_LocalInvocationIndex;
    uint row = 0u;
    s_scan[t] = value;
    sync_shared();
    for (uint offset = 1u; offset < uint(WORKGROUP); offset <<= 1u) {
        uint sum = s_scan[row + t];
        if (t >= offset) sum += s_scan[row + t - offset];
        row = uint(WORKGROUP) - row;
        s_scan[row + t] = sum;
        sync_shared();
    }
    total = s_scan[row + uint(WORKGROUP) - 1u];
    uint inclusive = s_scan[row + t];
    sync_shared();  // the next call overwrites the rows
    return inclusive - value;
}
