// CSG by intervals: the WGSL twin of src/accel/csg.rs (same steps, same
// order, same epsilon). Trees of at most CSG_FAST_MAX_LEAVES convex leaves
// take the truth-table evaluator at the end of this file instead. A CSG shape's `blas_root` is the first instruction
// of its postfix program in `csg_ops`; a leaf instruction pushes the spans
// of t where the ray is inside that leaf (`load_csg_leaf(arg)`), a set
// operation pops two span lists and pushes their union, intersection or
// difference. A list is a sorted run of endpoints (entry, exit, ...), each
// with the outward normal of the partial solid (CSG object space, not unit)
// and the leaf's material. The first endpoint in (t_min, t_max) is the hit.
//
// Fixed storage: CSG_EVAL_STACK entries of 2 * CSG_EVAL_INTERVALS
// endpoints, plus one scratch entry, 12 bytes an endpoint (t, packed
// normal, material and flip bit): ~1 KB per invocation at the full lengths
// (on CPU drivers a private array costs in proportion to its size, zeroed
// where it is declared, so each scene's kernel has only the lengths its
// programs need). Trees that could
// need more are refused at load (see
// src/scene/csg.rs); a mesh leaf crossed more than CSG_MESH_MAX_CROSSINGS
// times, or a list that overflows anyway, sets `overflowed` (a magenta
// pixel and a count), never a silent wrong answer. Every instruction and
// every sweep step spends one `take_step()` of the invocation's budget.
//
// Epsilon strategy (csg_push): two consecutive endpoints of a list closer
// than CSG_EPS_ABS + CSG_EPS_REL * |t| cancel each other, after every leaf
// and every operation: a gap that short is closed, an interval that short is
// dropped. Coincident surfaces of two leaves differ only by rounding (~1e-7
// relative), grazing rays give vanishing intervals: both resolve the same
// way at every pixel, so no speckles.
//
// Includes: after intersect.wgsl and traverse.wgsl; `csg_ops` and
// `csg_leaves` are the scene's (lib/scene_bindings.wgsl), their structs in
// lib/types.wgsl.

// Pipelines for scenes without CSG set this to false, which removes the CSG
// code from the traversal: on lavapipe its mere presence in the traversal
// loop made non-CSG scenes ~2x slower (measured, release, 640x360).
override CSG_ENABLED: bool = true;

const SHAPE_CSG: u32 = 7u;
const CSG_OP_END: u32 = 0u;
const CSG_OP_LEAF: u32 = 1u;
const CSG_OP_UNION: u32 = 2u;
const CSG_OP_INTERSECTION: u32 = 3u;
const CSG_OP_DIFFERENCE: u32 = 4u;
const CSG_NO_MATERIAL: u32 = 0xffffffffu;
// CSG_MESH_MAX_CROSSINGS, CSG_FAR, CSG_EPS_ABS, CSG_EPS_REL and the
// evaluator's lengths in this module, CSG_EVAL_STACK stack entries of
// CSG_EVAL_INTERVALS intervals (CSG_STACK and CSG_MAX_INTERVALS, or what
// the scene's programs need: src/accel/mod.rs, PrivateSizes), come from
// the generated lib/limits.wgsl (src/gpu/shader.rs).
// Endpoints per stack entry.
const CSG_ENDPOINTS: u32 = 2u * CSG_EVAL_INTERVALS;
// The stack's entries and one scratch entry.
const CSG_SLOTS: u32 = CSG_EVAL_STACK + 1u;
const CSG_STORE_ENDPOINTS: u32 = CSG_SLOTS * CSG_ENDPOINTS;

// Endpoint storage: entry s of the stack lives in physical slot
// slot[s]; endpoint k of slot p is at p * CSG_ENDPOINTS + k (CSG_STORE_ENDPOINTS = CSG_SLOTS * CSG_ENDPOINTS).
// `n` is the octahedral normal (pack2x16snorm); `tag` is the leaf material
// (low 31 bits, 0x7fffffff: none) and bit 31 flips the normal.
struct CsgStore {
    t: array<f32, CSG_STORE_ENDPOINTS>,
    n: array<u32, CSG_STORE_ENDPOINTS>,
    tag: array<u32, CSG_STORE_ENDPOINTS>,
    len: array<u32, CSG_SLOTS>,
    slot: array<u32, CSG_SLOTS>,
}

// Module scope: zeroed once per invocation (a function-local store, zeroed
// at every tree tested, measured twice as slow on lavapipe).
var<private> csg_store: CsgStore;

const CSG_TAG_FLIP: u32 = 0x80000000u;
const CSG_TAG_NONE: u32 = 0x7fffffffu;

fn csg_pack_normal(n: vec3<f32>) -> u32 {
    let m = n / max(abs(n.x) + abs(n.y) + abs(n.z), 1.0e-30);
    var e = m.xy;
    if m.z < 0.0 {
        e = (1.0 - abs(m.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), m.xy >= vec2<f32>(0.0));
    }
    return pack2x16snorm(e);
}

fn csg_unpack_normal(u: u32, tag: u32) -> vec3<f32> {
    let e = unpack2x16snorm(u);
    var n = vec3<f32>(e, 1.0 - abs(e.x) - abs(e.y));
    let f = max(-n.z, 0.0);
    n.x += select(f, -f, n.x >= 0.0);
    n.y += select(f, -f, n.y >= 0.0);
    return select(n, -n, (tag & CSG_TAG_FLIP) != 0u);
}

fn csg_tag(material: u32) -> u32 {
    return select(material, CSG_TAG_NONE, material == CSG_NO_MATERIAL);
}
// The material of the last CSG hit (CSG_NO_MATERIAL: the instance's).
var<private> object_material: u32;

fn csg_eps(t: f32) -> f32 {
    return CSG_EPS_ABS + CSG_EPS_REL * abs(t);
}

// Appends an endpoint to slot p, or cancels it against the last one when
// the two are closer than csg_eps (see the epsilon strategy above).
fn csg_push(st: ptr<private, CsgStore>, p: u32, t: f32, n: u32, tag: u32) {
    let len = (*st).len[p];
    let base = p * CSG_ENDPOINTS;
    if len > 0u && t - (*st).t[base + len - 1u] < csg_eps(t) {
        (*st).len[p] = len - 1u;
        return;
    }
    if len >= CSG_ENDPOINTS {
        overflowed = true;
        return;
    }
    (*st).t[base + len] = t;
    (*st).n[base + len] = n;
    (*st).tag[base + len] = tag;
    (*st).len[p] = len + 1u;
}

// Every crossing of the line with a mesh leaf, sorted, reduced to
// alternating entries and exits (an entry runs against the geometric
// normal; a repeated entry or exit, the same crossing found twice on a
// shared edge, is skipped).
// The crossings of the mesh leaf being collected, sorted by t. Module
// scope for the reason csg_store is: zeroed once per invocation, not at
// every mesh leaf tested; only the first `count` entries are read.
struct CsgCrossings {
    t: array<f32, CSG_MESH_MAX_CROSSINGS>,
    n: array<vec3<f32>, CSG_MESH_MAX_CROSSINGS>,
    entering: array<bool, CSG_MESH_MAX_CROSSINGS>,
}
var<private> csg_crossings: CsgCrossings;

fn csg_mesh_leaf(st: ptr<private, CsgStore>, p: u32, leaf: GpuCsgLeaf, o: vec3<f32>, d: vec3<f32>, base: u32) {
    var count = 0u;
    let inv_d = 1.0 / d;
    let root_node = load_node(leaf.blas_root);
    let ray = triangle_ray(o, d, root_node.bounds_min, root_node.bounds_max);
    // `trace_stack` above `base`, where the caller's entries end, as intersect_mesh does.
    var sp = base;
    let root_span = node_span(root_node, o, inv_d, -CSG_FAR, CSG_FAR);
    var current = select(NO_HIT, leaf.blas_root, root_span.x <= root_span.y);
    loop {
        if current == NO_HIT {
            if sp == base {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !take_step() {
            return;
        }
        let node = load_node(current);
        if node.count == 0u {
            current = descend(node, o, inv_d, -CSG_FAR, CSG_FAR, &sp, false);
            continue;
        }
        current = NO_HIT;
        for (var k = node.left_or_first; k < node.left_or_first + node.count; k++) {
            let h = intersect_triangle(ray, k, -CSG_FAR, CSG_FAR);
            if !h.hit {
                continue;
            }
            if count >= CSG_MESH_MAX_CROSSINGS {
                overflowed = true;
                return;
            }
            // Insertion sort by t; ties keep discovery order.
            var at = count;
            while at > 0u && csg_crossings.t[at - 1u] > h.t {
                csg_crossings.t[at] = csg_crossings.t[at - 1u];
                csg_crossings.n[at] = csg_crossings.n[at - 1u];
                csg_crossings.entering[at] = csg_crossings.entering[at - 1u];
                at -= 1u;
            }
            csg_crossings.t[at] = h.t;
            csg_crossings.n[at] = h.normal;
            csg_crossings.entering[at] = dot(h.geometric, d) < 0.0;
            count += 1u;
        }
    }
    var inside = false;
    for (var k = 0u; k < count; k++) {
        let entering = csg_crossings.entering[k];
        if entering != inside {
            let n = csg_pack_normal((leaf.csg_normal_from_leaf * vec4<f32>(csg_crossings.n[k], 0.0)).xyz);
            csg_push(st, p, csg_crossings.t[k], n, csg_tag(leaf.material));
            inside = entering;
        }
    }
    if inside {
        (*st).len[p] -= 1u;
    }
}

// The spans of the whole line inside a leaf, into slot p.
fn csg_leaf(st: ptr<private, CsgStore>, p: u32, leaf: GpuCsgLeaf, o: vec3<f32>, d: vec3<f32>, base: u32) {
    (*st).len[p] = 0u;
    let lo = (leaf.leaf_from_csg * vec4<f32>(o, 1.0)).xyz;
    let ld = (leaf.leaf_from_csg * vec4<f32>(d, 0.0)).xyz;
    if leaf.kind == SHAPE_MESH {
        csg_mesh_leaf(st, p, leaf, lo, ld, base);
        return;
    }
    // Convex: the first boundary on the line is the entry, the next the
    // exit. One call site in a loop of two: half the code, which lavapipe
    // runs faster (it inlines everything).
    let tag = csg_tag(leaf.material);
    var t_from = -CSG_FAR;
    for (var k = 0u; k < 2u; k++) {
        let h = intersect_analytic(leaf.kind, leaf.params, lo, ld, t_from, CSG_FAR);
        if !h.hit {
            // Tangent (an entry without an exit): no interval.
            (*st).len[p] = 0u;
            return;
        }
        csg_push(st, p, h.t, csg_pack_normal((leaf.csg_normal_from_leaf * vec4<f32>(h.normal, 0.0)).xyz), tag);
        t_from = h.t;
    }
}

// Slot `out` = slot a (op) slot b, by one sweep over both sorted lists.
// Endpoints of a subtracted solid get flipped normals: its entry is where
// the result is left, and the outward normal there points into it.
fn csg_combine(st: ptr<private, CsgStore>, op: u32, a: u32, b: u32, out: u32) {
    (*st).len[out] = 0u;
    let na = (*st).len[a];
    let nb = (*st).len[b];
    var i = 0u;
    var j = 0u;
    var in_a = false;
    var in_b = false;
    loop {
        if i >= na && j >= nb {
            break;
        }
        if op != CSG_OP_UNION && i >= na {
            break;
        }
        if op == CSG_OP_INTERSECTION && j >= nb {
            break;
        }
        if !take_step() {
            return;
        }
        var k: u32;
        var flip = 0u;
        if j >= nb || (i < na && (*st).t[a * CSG_ENDPOINTS + i] <= (*st).t[b * CSG_ENDPOINTS + j]) {
            k = a * CSG_ENDPOINTS + i;
            i += 1u;
            in_a = !in_a;
        } else {
            k = b * CSG_ENDPOINTS + j;
            j += 1u;
            in_b = !in_b;
            if op == CSG_OP_DIFFERENCE {
                flip = CSG_TAG_FLIP;
            }
        }
        var inside: bool;
        if op == CSG_OP_UNION {
            inside = in_a || in_b;
        } else if op == CSG_OP_INTERSECTION {
            inside = in_a && in_b;
        } else {
            inside = in_a && !in_b;
        }
        if inside != (((*st).len[out] & 1u) == 1u) {
            csg_push(st, out, (*st).t[k], (*st).n[k], (*st).tag[k] ^ flip);
        }
    }
}

// Whether the ray (o, d) may meet the solid in (t_min, t_max): its segment
// there meets the bounding sphere the shape's params hold (centre, radius;
// src/scene/csg.rs Csg::bounding_sphere, wide enough for rounding). Twin
// of accel::csg::bound_may_hit: the line's closest point to the centre,
// the reach 1e-5 of the origin's distance wider.
fn csg_bound_may_hit(bound: vec4<f32>, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    let oc = o - bound.xyz;
    let dd = dot(d, d);
    let t_mid = -dot(oc, d) / dd;
    let p = oc + d * t_mid;
    let reach = bound.w + 1.0e-5 * length(oc);
    let gap = reach * reach - dot(p, p);
    if gap < 0.0 {
        return false;
    }
    let half = sqrt(gap / dd);
    return t_mid + half > t_min && t_mid - half < t_max;
}

// The closest boundary of the CSG program at `start` in (t_min, t_max), in
// CSG object space; sets object_material.
// Mesh leaves use `trace_stack` above `base`, where the caller's entries end.
fn intersect_csg(start: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, base: u32) -> ObjectHit {
    for (var s = 0u; s < CSG_SLOTS; s++) {
        csg_store.slot[s] = s;
    }
    var sp = 0u;
    var pc = start;
    loop {
        if !take_step() {
            return no_hit();
        }
        let op = load_csg_op(pc);
        pc += 1u;
        if op.op == CSG_OP_END {
            break;
        }
        if op.op == CSG_OP_LEAF {
            if sp >= CSG_EVAL_STACK {
                overflowed = true;
                return no_hit();
            }
            csg_leaf(&csg_store, csg_store.slot[sp], load_csg_leaf(op.arg), o, d, base);
        } else {
            if sp < 2u {
                overflowed = true;
                return no_hit();
            }
            var a = csg_store.slot[sp - 2u];
            var b = csg_store.slot[sp - 1u];
            if op.arg == 1u {
                let swap = a;
                a = b;
                b = swap;
            }
            // The free slot above the top takes the result; it then becomes
            // entry sp - 2 and that entry's old slot the free one.
            let out = csg_store.slot[sp];
            csg_combine(&csg_store, op.op, a, b, out);
            csg_store.slot[sp] = csg_store.slot[sp - 2u];
            csg_store.slot[sp - 2u] = out;
            sp -= 2u;
        }
        sp += 1u;
        if overflowed {
            return no_hit();
        }
    }
    if sp != 1u {
        overflowed = true;
        return no_hit();
    }
    let r = csg_store.slot[0];
    let len = csg_store.len[r];
    for (var k = 0u; k < len; k++) {
        if !take_step() {
            return no_hit();
        }
        let i = r * CSG_ENDPOINTS + k;
        let t = csg_store.t[i];
        if t > t_min {
            if t < t_max {
                let tag = csg_store.tag[i];
                object_material = select(tag & CSG_TAG_NONE, CSG_NO_MATERIAL, (tag & CSG_TAG_NONE) == CSG_TAG_NONE);
                let n = csg_unpack_normal(csg_store.n[i], tag);
                return ObjectHit(true, t, n, n);
            }
            break;
        }
    }
    return no_hit();
}

// ---------------------------------------------------------------------------
// Programs of at most CSG_FAST_MAX_LEAVES convex leaves (sphere, box,
// cylinder, cone) by their truth table instead of interval lists: each
// leaf's span of the line, then every span end classified. An end at t is a
// boundary of the solid where the solid holds the point t - csg_eps(t) and
// not t + csg_eps(t), or the other way round; the solid holds a point when
// bit m of the table is set, m having bit i where leaf i holds it
// (src/accel/csg.rs, fast_table). The nearest boundary in (t_min, t_max) is
// the hit. No private arrays and no loops: on lavapipe the interval lists'
// stores and sweeps cost more than the leaves (docs/performance.md).
//
// The same answers as the lists, up to what falls within csg_eps of an end
// (the lists merge ends that close after each operation, this after the
// whole tree): ends closer than csg_eps(t) count as one, a span or gap of
// the solid shorter than csg_eps(t) is dropped or closed, and a leaf's own
// span that short is empty, as there. Where ends of two leaves coincide
// (a face cut flush), the nearest of them gives the normal and material.

// The most leaves of the scene's programs evaluated this way (0: none, and
// the code below is left out); CSG_INTERPRETER false leaves the interval
// lists' code out (every CSG program of the scene is evaluated this way).
// Set per pipeline (src/render/trace.rs, Variant).
override CSG_FAST_LEAVES: u32 = CSG_FAST_MAX_LEAVES;
override CSG_INTERPRETER: bool = true;

// A leaf's span of the whole line in leaf space: entry t0 and exit t1,
// and which of the leaf's candidate boundaries (csg_leaf_span) each is, for
// its normal (csg_span_normal), computed only for the hit.
struct CsgSpan {
    ok: bool,
    t0: f32,
    t1: f32,
    i0: u32,
    i1: u32,
}

// Of up to 4 candidate boundaries (ok: on the surface), the index of the
// nearest after `after` and before CSG_FAR (4: none), ties to the first.
// The intersect_* functions pick the same candidates in the same order,
// so the span ends are theirs bit for bit.
fn csg_nearest_after(t: vec4<f32>, ok: vec4<bool>, after: f32) -> u32 {
    var best = 4u;
    var bt = CSG_FAR;
    var take = ok.x && t.x > after && t.x < bt;
    best = select(best, 0u, take);
    bt = select(bt, t.x, take);
    take = ok.y && t.y > after && t.y < bt;
    best = select(best, 1u, take);
    bt = select(bt, t.y, take);
    take = ok.z && t.z > after && t.z < bt;
    best = select(best, 2u, take);
    bt = select(bt, t.z, take);
    take = ok.w && t.w > after && t.w < bt;
    return select(best, 3u, take);
}

// The outward normal of candidate i (csg_leaf_span's order) at t: the
// intersect function's normal there.
fn csg_span_normal(kind: u32, p4: vec4<f32>, o: vec3<f32>, d: vec3<f32>, i: u32, t: f32) -> vec3<f32> {
    let p = o + d * t;
    switch kind {
        case SHAPE_SPHERE: {
            return p / p4.x;
        }
        case SHAPE_BOX: {
            return box_normal(p / p4.xyz);
        }
        case SHAPE_CYLINDER: {
            if i < 2u {
                return vec3<f32>(p.x, 0.0, p.z) / p4.x;
            }
            return vec3<f32>(0.0, select(-1.0, 1.0, i == 2u), 0.0);
        }
        default: {
            if i < 2u {
                let k = p4.x / p4.y;
                return normalize(vec3<f32>(p.x, k * k * (p4.y - p.y), p.z));
            }
            return vec3<f32>(0.0, -1.0, 0.0);
        }
    }
}

// The span of the line (o, d) inside a convex leaf: the boundaries the
// intersect_* functions give from -CSG_FAR and then from the first one,
// found together (their candidates, in their order), dropped where the
// two are closer than csg_eps as csg_push drops them.
fn csg_leaf_span(kind: u32, p4: vec4<f32>, o: vec3<f32>, d: vec3<f32>) -> CsgSpan {
    var t = vec4<f32>(CSG_FAR);
    var ok = vec4<bool>(false);
    switch kind {
        case SHAPE_SPHERE: {
            let a = dot(d, d);
            let b = dot(o, d);
            let c = dot(o, o) - p4.x * p4.x;
            let disc = b * b - a * c;
            let s = sqrt(max(disc, 0.0));
            t = vec4<f32>((-b - s) / a, (-b + s) / a, CSG_FAR, CSG_FAR);
            ok = vec4<bool>(disc >= 0.0, disc >= 0.0, false, false);
        }
        case SHAPE_BOX: {
            let inv = 1.0 / d;
            let t1 = (-p4.xyz - o) * inv;
            let t2 = (p4.xyz - o) * inv;
            let lo = min(t1, t2);
            let hi = max(t1, t2);
            let near = max(max(lo.x, lo.y), lo.z);
            let far = min(min(hi.x, hi.y), hi.z);
            t = vec4<f32>(near, far, CSG_FAR, CSG_FAR);
            ok = vec4<bool>(near <= far, near <= far, false, false);
        }
        case SHAPE_CYLINDER: {
            let r = p4.x;
            let half = p4.y * 0.5;
            let a = d.x * d.x + d.z * d.z;
            let b = o.x * d.x + o.z * d.z;
            let c = o.x * o.x + o.z * o.z - r * r;
            let disc = b * b - a * c;
            let s = sqrt(max(disc, 0.0));
            let r0 = (-b - s) / a;
            let r1 = (-b + s) / a;
            let body = a > 0.0 && disc >= 0.0;
            let c0 = (half - o.y) / d.y;
            let c1 = (-half - o.y) / d.y;
            let p0 = o + d * c0;
            let p1 = o + d * c1;
            let caps = d.y != 0.0;
            t = vec4<f32>(r0, r1, c0, c1);
            ok = vec4<bool>(
                body && abs(o.y + d.y * r0) <= half,
                body && abs(o.y + d.y * r1) <= half,
                caps && p0.x * p0.x + p0.z * p0.z <= r * r,
                caps && p1.x * p1.x + p1.z * p1.z <= r * r,
            );
        }
        case SHAPE_CONE: {
            let r = p4.x;
            let height = p4.y;
            let k = r / height;
            let k2 = k * k;
            let hy = height - o.y;
            let a = d.x * d.x + d.z * d.z - k2 * d.y * d.y;
            let b = o.x * d.x + o.z * d.z + k2 * hy * d.y;
            let c = o.x * o.x + o.z * o.z - k2 * hy * hy;
            let disc = b * b - a * c;
            let s = sqrt(max(disc, 0.0));
            let q0 = (-b - s) / a;
            let q1 = (-b + s) / a;
            let quadratic = abs(a) > 1e-12;
            let linear = -c / (2.0 * b);
            let r0 = select(linear, min(q0, q1), quadratic);
            let r1 = max(q0, q1);
            let n_roots = select(select(0u, 1u, abs(b) > 1e-12), select(0u, 2u, disc >= 0.0), quadratic);
            let y0 = o.y + d.y * r0;
            let y1 = o.y + d.y * r1;
            let tb = -o.y / d.y;
            let pb = o + d * tb;
            t = vec4<f32>(r0, r1, tb, CSG_FAR);
            ok = vec4<bool>(
                n_roots >= 1u && y0 >= 0.0 && y0 <= height,
                n_roots >= 2u && y1 >= 0.0 && y1 <= height,
                d.y != 0.0 && pb.x * pb.x + pb.z * pb.z <= r * r,
                false,
            );
        }
        default: {}
    }
    let i0 = csg_nearest_after(t, ok, -CSG_FAR);
    let t0 = t[min(i0, 3u)];
    let i1 = csg_nearest_after(t, ok, select(t0, CSG_FAR, i0 == 4u));
    let t1 = t[min(i1, 3u)];
    let ok_span = i1 != 4u && t1 - t0 >= csg_eps(t1);
    return CsgSpan(ok_span, t0, t1, i0, i1);
}

// One leaf of a program evaluated by its table, in CSG space: its span
// (lo, hi; both CSG_FAR where empty, so that no point is inside), which
// candidates of the leaf its ends are (entry + 4 * exit) and its word of
// the table.
struct CsgSlot {
    lo: f32,
    hi: f32,
    ends: u32,
    word: u32,
}

// Leaf i's local ray.
struct CsgLeafRay {
    o: vec3<f32>,
    d: vec3<f32>,
}

fn csg_leaf_ray(leaf: GpuCsgLeaf, o: vec3<f32>, d: vec3<f32>) -> CsgLeafRay {
    return CsgLeafRay((leaf.leaf_from_csg * vec4<f32>(o, 1.0)).xyz, (leaf.leaf_from_csg * vec4<f32>(d, 0.0)).xyz);
}

fn csg_fast_slot(i: u32, count: u32, first: u32, o: vec3<f32>, d: vec3<f32>) -> CsgSlot {
    var slot = CsgSlot(CSG_FAR, CSG_FAR, 0u, 0u);
    if i < count {
        let leaf = load_csg_leaf(first + i);
        slot.word = leaf.table;
        let ray = csg_leaf_ray(leaf, o, d);
        let span = csg_leaf_span(leaf.kind, leaf.params, ray.o, ray.d);
        if span.ok {
            slot = CsgSlot(span.t0, span.t1, span.i0 + 4u * span.i1, leaf.table);
        }
    }
    return slot;
}

// The spans of leaves 0-3 (a) and 4-7 (b), and the table's words.
struct CsgSpans {
    lo_a: vec4<f32>,
    hi_a: vec4<f32>,
    lo_b: vec4<f32>,
    hi_b: vec4<f32>,
    words_a: vec4<u32>,
    words_b: vec4<u32>,
}

// Whether the solid holds the point at x.
fn csg_fast_holds(s: CsgSpans, x: f32) -> bool {
    let bits = vec4<u32>(1u, 2u, 4u, 8u);
    let in_a = (vec4<f32>(x) >= s.lo_a) & (vec4<f32>(x) < s.hi_a);
    var m = dot(select(vec4<u32>(0u), bits, in_a), vec4<u32>(1u));
    var word = s.words_a.x;
    if CSG_FAST_LEAVES > 4u {
        let in_b = (vec4<f32>(x) >= s.lo_b) & (vec4<f32>(x) < s.hi_b);
        m |= dot(select(vec4<u32>(0u), bits, in_b), vec4<u32>(1u)) << 4u;
        if CSG_FAST_LEAVES > 5u {
            let w = m >> 5u;
            let q = select(s.words_a, s.words_b, w >= 4u);
            word = q[w & 3u];
        }
    }
    return ((word >> (m & 31u)) & 1u) == 1u;
}

// The nearest span end after `after`, CSG_FAR where none.
fn csg_fast_next(s: CsgSpans, after: f32) -> f32 {
    let far = vec4<f32>(CSG_FAR);
    var m = min(select(far, s.lo_a, s.lo_a > vec4<f32>(after)), select(far, s.hi_a, s.hi_a > vec4<f32>(after)));
    if CSG_FAST_LEAVES > 4u {
        m = min(m, min(select(far, s.lo_b, s.lo_b > vec4<f32>(after)), select(far, s.hi_b, s.hi_b > vec4<f32>(after))));
    }
    return min(min(m.x, m.y), min(m.z, m.w));
}

// Of the four slots from `base` (lo, hi), the first end at t (slot order,
// entry before exit) as slot times 2, plus 1 for an exit; else `code`.
fn csg_fast_pick4(code: u32, lo: vec4<f32>, hi: vec4<f32>, t: f32, base: u32) -> u32 {
    var c = code;
    c = select(c, 2u * base + 7u, hi.w == t);
    c = select(c, 2u * base + 6u, lo.w == t);
    c = select(c, 2u * base + 5u, hi.z == t);
    c = select(c, 2u * base + 4u, lo.z == t);
    c = select(c, 2u * base + 3u, hi.y == t);
    c = select(c, 2u * base + 2u, lo.y == t);
    c = select(c, 2u * base + 1u, hi.x == t);
    return select(c, 2u * base, lo.x == t);
}

// The first span end at t, as csg_fast_pick4 gives it.
fn csg_fast_end_at(s: CsgSpans, t: f32) -> u32 {
    var code = 0u;
    if CSG_FAST_LEAVES > 4u {
        code = csg_fast_pick4(code, s.lo_b, s.hi_b, t, 4u);
    }
    return csg_fast_pick4(code, s.lo_a, s.hi_a, t, 0u);
}

// The closest boundary in (t_min, t_max) of the program whose
// GpuShape.csg_fast is `fast`, in CSG object space; sets object_material.
// The span ends are visited nearest first, each classified, until one is a
// boundary: lanes stop at their first (usually the first or second end)
// rather than classifying all of them.
fn intersect_csg_fast(fast: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> ObjectHit {
    let count = fast >> CSG_FAST_COUNT_SHIFT;
    let first = fast & ((1u << CSG_FAST_COUNT_SHIFT) - 1u);
    let empty = CsgSlot(CSG_FAR, CSG_FAR, 0u, 0u);
    let s0 = csg_fast_slot(0u, count, first, o, d);
    var s1 = empty;
    var s2 = empty;
    var s3 = empty;
    var s4 = empty;
    var s5 = empty;
    var s6 = empty;
    var s7 = empty;
    if CSG_FAST_LEAVES > 1u {
        s1 = csg_fast_slot(1u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 2u {
        s2 = csg_fast_slot(2u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 3u {
        s3 = csg_fast_slot(3u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 4u {
        s4 = csg_fast_slot(4u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 5u {
        s5 = csg_fast_slot(5u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 6u {
        s6 = csg_fast_slot(6u, count, first, o, d);
    }
    if CSG_FAST_LEAVES > 7u {
        s7 = csg_fast_slot(7u, count, first, o, d);
    }
    let s = CsgSpans(
        vec4<f32>(s0.lo, s1.lo, s2.lo, s3.lo),
        vec4<f32>(s0.hi, s1.hi, s2.hi, s3.hi),
        vec4<f32>(s4.lo, s5.lo, s6.lo, s7.lo),
        vec4<f32>(s4.hi, s5.hi, s6.hi, s7.hi),
        vec4<u32>(s0.word, s1.word, s2.word, s3.word),
        vec4<u32>(s4.word, s5.word, s6.word, s7.word),
    );
    let limit = min(t_max, CSG_FAR);
    var t = t_min;
    var entering = false;
    var found = false;
    // Each step moves to a later end: at most 2 per leaf.
    for (var step = 0u; step < 2u * CSG_FAST_LEAVES; step++) {
        t = csg_fast_next(s, t);
        if t >= limit {
            break;
        }
        let e = csg_eps(t);
        entering = csg_fast_holds(s, t + e);
        if csg_fast_holds(s, t - e) != entering {
            found = true;
            break;
        }
    }
    if !found {
        return no_hit();
    }
    let code = csg_fast_end_at(s, t);
    let slot = code / 2u;
    let exit = (code & 1u) == 1u;
    let ends_a = vec4<u32>(s0.ends, s1.ends, s2.ends, s3.ends);
    let ends_b = vec4<u32>(s4.ends, s5.ends, s6.ends, s7.ends);
    let which = select(ends_a, ends_b, slot >= 4u)[slot & 3u];
    let candidate = select(which & 3u, which >> 2u, exit);
    let leaf = load_csg_leaf(first + slot);
    let ray = csg_leaf_ray(leaf, o, d);
    let n_leaf = csg_span_normal(leaf.kind, leaf.params, ray.o, ray.d, candidate, t);
    // Entering the solid through a leaf's exit (a subtracted leaf), or
    // leaving it through an entry: the leaf's normal points inwards.
    let n_out = select(n_leaf, -n_leaf, entering == exit);
    object_material = leaf.material;
    let n = (leaf.csg_normal_from_leaf * vec4<f32>(n_out, 0.0)).xyz;
    return ObjectHit(true, t, n, n);
}
