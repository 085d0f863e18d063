// GPU sort, first pass: the cull and the keys of every entry of the row list (the
// request's rows: the whole scene or a level-of-detail choice's spans, ascending), as
// raygs_viewer/sort/cull.py computes them (Cull._may_be_seen, Cull._chunk), bit for bit.
//
// Per entry it writes the scene row where some cull camera may see the gaussian (else
// NO_ROW) and its keys (depth from the sort camera, distance from the snapped centre);
// per workgroup, how many entries it kept (the scan pass turns those into where each
// group's kept entries start: compaction in scene order by a prefix sum). The ranges the
// keys are quantised over (depth: over what is kept; distance: over every candidate,
// kept or not) are min and max of ordered_bits in shared memory, then one atomic per
// group in Summary: exact whatever order the atomics land in.
#include "sort_common.glsl"
#include "sort_exact.glsl"

layout(local_size_x = WORKGROUP) in;

layout(std430, binding = 0) readonly buffer Positions { float positions[]; };  // (N, 3) float32
// (radius, root_kappa) per gaussian from Cull.support(p_min); root_kappa's sign bit set:
// not a candidate (opacity <= p_min), which no camera keeps.
layout(std430, binding = 1) readonly buffer Supports { vec2 supports[]; };
layout(std430, binding = 2) readonly buffer Spans { uvec2 spans[]; };  // (first row, first entry), ascending
layout(std430, binding = 3) writeonly buffer Slots { uint slots[]; };
layout(std430, binding = 4) writeonly buffer Values { vec2 values[]; };  // (depth, distance)
layout(std430, binding = 5) writeonly buffer GroupCounts { uint group_counts[]; };

// One cull camera, its float32 constants computed on the host as cull.py computes them.
struct CullCamera {
    vec4 rows[3];    // (R_i0, R_i1, R_i2, t_i)
    vec4 x_planes;   // cull.side_planes: (a, b) of the low and the high x plane
    vec4 y_planes;   // ... of the y planes
    vec4 slack;      // x: cull.cull_slack
};
layout(std430, binding = 7) readonly buffer CullCameras { CullCamera cameras[]; };

uniform uint u_total;       // entries in the row list
uniform uint u_spans;       // spans in Spans
uniform uint u_cameras;     // cameras in CullCameras
uniform bool u_frustum;     // the side planes (a request's dilation is not None)
uniform bool u_dilate;      // the dilation term (a dilation other than 0)
uniform float u_dilation;   // float32(dilation)
uniform float u_widening;   // cull.RADIUS_WIDENING
uniform bool u_depth;       // compute the depth key ...
uniform bool u_distance;    // ... the distance key
uniform vec4 u_depth_row;   // row 2 of the sort camera: (R_20, R_21, R_22, t_2)
uniform vec3 u_centre;      // keys.snapped_centre of the sort camera

shared uint s_kept;
shared uint s_depth_low, s_depth_high, s_distance_low, s_distance_high;

// The scene row of list entry ``entry``: a binary search for its span.
uint row_of(uint entry) {
    uint low = 0u, high = u_spans;  // spans[low].y <= entry < spans[high].y (high == u_spans: the end)
    while (high - low > 1u) {
        uint middle = (low + high) / 2u;
        if (spans[middle].y <= entry) low = middle;
        else high = middle;
    }
    return spans[low].x + (entry - spans[low].y);
}

// Whether ``camera`` may see the support sphere of a candidate at ``p`` (Cull._may_be_seen).
bool may_be_seen(CullCamera camera, vec3 p, float support_radius, float root_kappa) {
    precise vec3 mu = vec3(camera_axis(p, camera.rows[0]), camera_axis(p, camera.rows[1]),
                           camera_axis(p, camera.rows[2]));
    precise float radius = support_radius;
    if (u_dilate) {
        precise float xx = mu.x * mu.x;
        precise float yy = mu.y * mu.y;
        precise float zz = mu.z * mu.z;
        precise float sum = xx + yy;
        sum = sum + zz;
        precise float term = sqrt_rn(sum);
        term = term * root_kappa;
        term = term * u_dilation;
        radius = radius + term;
    }
    radius = radius * u_widening;
    radius = radius + camera.slack.x;
    precise float bound = -radius;
    bool keep = mu.z > bound;
    if (u_frustum) {
        for (int side = 0; side < 2; ++side) {
            precise float x_across = mu.x * camera.x_planes[2 * side];
            precise float x_along = mu.z * camera.x_planes[2 * side + 1];
            precise float x_inside = x_across + x_along;
            keep = keep && x_inside > bound;
        }
        for (int side = 0; side < 2; ++side) {
            precise float y_across = mu.y * camera.y_planes[2 * side];
            precise float y_along = mu.z * camera.y_planes[2 * side + 1];
            precise float y_inside = y_across + y_along;
            keep = keep && y_inside > bound;
        }
    }
    return keep;
}

void main() {
    uint t = gl_LocalInvocationIndex;
    uint group = gl_WorkGroupID.x;
    if (t == 0u) {
        s_kept = 0u;
        s_depth_low = s_distance_low = 0xFFFFFFFFu;  // ordered_bits never gives these two
        s_depth_high = s_distance_high = 0u;
    }
    sync_shared();
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint entry = group * TILE + i * uint(WORKGROUP) + t;  // striped: neighbours read neighbours
        if (entry >= u_total) continue;
        uint row = row_of(entry);
        vec3 p = vec3(positions[3u * row], positions[3u * row + 1u], positions[3u * row + 2u]);
        vec2 support = supports[row];
        uint kappa_bits = floatBitsToUint(support.y);
        bool candidate = (kappa_bits & 0x80000000u) == 0u;
        float root_kappa = uintBitsToFloat(kappa_bits & 0x7FFFFFFFu);
        bool seen = false;
        for (uint c = 0u; candidate && !seen && c < u_cameras; ++c) {
            seen = may_be_seen(cameras[c], p, support.x, root_kappa);
        }
        slots[entry] = seen ? row : NO_ROW;
        vec2 keys = vec2(0.0);
        if (u_depth) {
            keys.x = camera_axis(p, u_depth_row);
            if (seen) {
                atomicMin(s_depth_low, ordered_bits(keys.x));
                atomicMax(s_depth_high, ordered_bits(keys.x));
            }
        }
        if (u_distance) {
            keys.y = centre_distance(p, u_centre);
            if (candidate && !is_nan(keys.y)) {  // NaN: a NaN position, which no scene reader keeps
                atomicMin(s_distance_low, ordered_bits(keys.y));
                atomicMax(s_distance_high, ordered_bits(keys.y));
            }
        }
        values[entry] = keys;
        if (seen) atomicAdd(s_kept, 1u);
    }
    sync_shared();
    if (t == 0u) {
        group_counts[group] = s_kept;
        if (s_depth_low != 0xFFFFFFFFu) {
            atomicMin(summary.depth_low, s_depth_low);
            atomicMax(summary.depth_high, s_depth_high);
        }
        if (s_distance_low != 0xFFFFFFFFu) {
            atomicMin(summary.distance_low, s_distance_low);
            atomicMax(summary.distance_high, s_distance_high);
        }
    }
}
