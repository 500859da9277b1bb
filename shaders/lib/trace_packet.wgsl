// The top-level trace as a packet walk: the packet variant of
// lib/trace_bvh.wgsl, same signature and answers. Included by
// lib/traverse.wgsl, whose helpers it uses; src/gpu/shader.rs swaps it in
// for the ray batch (src/render/ray_batch.rs) on CPU adapters whose
// subgroups are 8 invocations wide (Gpu::packet_walk).
//
// Why: the CPU driver runs a subgroup of 8 invocations as one SIMD program,
// and a storage-buffer read at an index that differs per invocation is a
// loop over the 8 lanes, word by word (docs/performance.md). Walking on its
// own, each of 8 neighbouring rays reads the same BVH nodes and triangles
// near the root: 14 words a step, 8 times over. Here the 8 rays walk one
// tree together. A node is visited when any lane's ray enters its box
// within that lane's own interval, so the packet never skips a node that
// holds a lane's closest hit; each lane tests its own ray and keeps its own
// hit. Every index is the same on all 8 lanes, so each lane loads one or two
// of a step's 16 words and every lane reads all 16 by broadcast: two lane
// loops a step instead of 14.
//
// The walk needs all 8 invocations of the subgroup in it at once (a lane
// that is not there loads nothing), so the passes make every trace call
// together (lib/trace_bvh.wgsl). The ray batch walks packets wherever the
// device can; the trace pass only where the top-level tree is in storage
// (SceneBuffers::packet_trace): on the shipped scenes its packet walk
// measured slower than each ray walking alone (docs/performance-history.md,
// nineteenth session).

// The subgroup size this walk is written for (Gpu::packet_walk checks it).
const PACKET_LANES: u32 = 8u;
// BvhNode and GpuTriangle sizes in words.
const NODE_WORDS: u32 = 8u;
const TRIANGLE_WORDS: u32 = 24u;

// This invocation's lane in its subgroup (0..PACKET_LANES), set by
// `trace_converged`.
var<private> packet_lane: u32;

// A node as the packet walk carries it: its first child or item, with its
// item count in the top 3 bits (0 for inner nodes). Leaves hold at most 4
// triangles and 2 instances (src/accel/mod.rs); indices stay under 2^29.
const PACKET_NONE: u32 = 0xffffffffu;

fn packet_node(first: u32, count: u32) -> u32 {
    return first | (count << 29u);
}

fn box_span(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, t_min: f32, t_max: f32) -> vec2<f32> {
    return node_span(BvhNode(lo, 0u, hi, 0u), o, inv_d, t_min, t_max);
}

// Node i's 8 words, loaded one a lane and read by every lane: its box and
// its packed (first, count).
struct PacketNode {
    lo: vec3<f32>,
    hi: vec3<f32>,
    node: u32,
}

// subgroupBroadcast takes a constant lane, so the 8 words are spelled out.
fn packet_node_words(w: u32) -> PacketNode {
    let lo = vec3<f32>(bitcast<f32>(subgroupBroadcast(w, 0u)), bitcast<f32>(subgroupBroadcast(w, 1u)), bitcast<f32>(subgroupBroadcast(w, 2u)));
    let hi = vec3<f32>(bitcast<f32>(subgroupBroadcast(w, 4u)), bitcast<f32>(subgroupBroadcast(w, 5u)), bitcast<f32>(subgroupBroadcast(w, 6u)));
    return PacketNode(lo, hi, packet_node(subgroupBroadcast(w, 3u), subgroupBroadcast(w, 7u)));
}

fn packet_load_node(i: u32) -> PacketNode {
    return packet_node_words(node_words[i * NODE_WORDS + packet_lane]);
}

// Instance i's object_from_world (i the same on every lane). From storage
// (the copies' table is too big: the case the trace pass walks packets
// for) the lanes share out its first three rows' 12 words, else each lane
// reads the uniform copy.
fn packet_object_from_world(i: u32) -> mat4x4<f32> {
    if uniform_table(TABLE_INSTANCES) {
        return load_instance(i).object_from_world;
    }
    // Lane k: columns k / 4 and 2 + k / 4, row k % 4 (rows 3 unused).
    let a = instances[i].object_from_world[packet_lane >> 2u][packet_lane & 3u];
    let b = instances[i].object_from_world[2u + (packet_lane >> 2u)][packet_lane & 3u];
    return mat4x4<f32>(
        vec4<f32>(subgroupBroadcast(a, 0u), subgroupBroadcast(a, 1u), subgroupBroadcast(a, 2u), 0.0),
        vec4<f32>(subgroupBroadcast(a, 4u), subgroupBroadcast(a, 5u), subgroupBroadcast(a, 6u), 0.0),
        vec4<f32>(subgroupBroadcast(b, 0u), subgroupBroadcast(b, 1u), subgroupBroadcast(b, 2u), 0.0),
        vec4<f32>(subgroupBroadcast(b, 4u), subgroupBroadcast(b, 5u), subgroupBroadcast(b, 6u), 1.0),
    );
}

// One step of the packet's descent from the inner node whose children start
// at `first` (the two children are 16 consecutive words): a child is next
// when any lane's ray enters its box within that lane's (t_min, t_max); with
// both, the one nearer for most of the lanes that enter both goes first and
// the other is pushed. PACKET_NONE: neither (the caller pops).
fn packet_descend(first: u32, o: vec3<f32>, inv_d: vec3<f32>, t_min: f32, t_max: f32, sp: ptr<function, u32>) -> u32 {
    let base = first * NODE_WORDS + packet_lane;
    let c0 = packet_node_words(node_words[base]);
    let c1 = packet_node_words(node_words[base + NODE_WORDS]);
    let s0 = box_span(c0.lo, c0.hi, o, inv_d, t_min, t_max);
    let s1 = box_span(c1.lo, c1.hi, o, inv_d, t_min, t_max);
    let h0 = s0.x <= s0.y;
    let h1 = s1.x <= s1.y;
    let any0 = subgroupAny(h0);
    let any1 = subgroupAny(h1);
    if any0 && any1 {
        if *sp >= TRACE_STACK {
            overflowed = true;
            return PACKET_NONE;
        }
        let vote = subgroupAdd(select(0i, select(-1i, 1i, s0.x <= s1.x), h0 & h1));
        let near0 = vote >= 0i;
        trace_stack[*sp] = select(c0.node, c1.node, near0);
        *sp += 1u;
        return select(c1.node, c0.node, near0);
    }
    if any0 {
        return c0.node;
    }
    if any1 {
        return c1.node;
    }
    return PACKET_NONE;
}

// The packet's step budget: the least that any of its lanes has left of
// `steps_left` (so the same on every lane). Each step spends one of both on
// every lane; when it runs out the packet stops, and every lane in it
// reports the overflow (their walks were all cut short). A CSG shape's own
// walk spends from its lane's `steps_left` alone, so after one the packet
// takes the least again: no lane ever runs more loop iterations than its
// budget allows (lib/traverse.wgsl says why that matters).
var<private> packet_steps: u32;

fn packet_step() -> bool {
    if packet_steps == 0u {
        overflowed = true;
        return false;
    }
    packet_steps -= 1u;
    steps_left -= 1u;
    return true;
}

// intersect_mesh as a packet: the mesh's bottom-level tree is walked by the
// 8 lanes together (root `root`, the same on every lane), each lane's own
// object-space ray (o, d) in (t_min, t_max).
fn packet_mesh(root: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, base: u32) -> ObjectHit {
    // A mesh has no material of its own: the instance's (as in
    // intersect_instance_shape).
    object_material = CSG_NO_MATERIAL;
    let inv_d = 1.0 / d;
    let r = packet_load_node(root);
    let ray = triangle_ray(o, d, r.lo, r.hi);
    let rs = box_span(r.lo, r.hi, o, inv_d, t_min, t_max);
    var best = NO_HIT;
    var best_tuv = vec3<f32>(0.0);
    var t_best = t_max;
    var sp = base;
    var current = select(PACKET_NONE, r.node, subgroupAny(rs.x <= rs.y));
    loop {
        if current == PACKET_NONE {
            if sp == base {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !packet_step() {
            break;
        }
        let first = current & 0x1fffffffu;
        let count = current >> 29u;
        if count == 0u {
            current = packet_descend(first, o, inv_d, t_min, t_best, &sp);
            continue;
        }
        for (var k = first; k < first + count; k++) {
            // The corners p0, p1 (lanes 0-7) and p2 (lanes 0-3; 4-7 repeat it).
            let w = k * TRIANGLE_WORDS + packet_lane;
            let w01 = triangle_words[w];
            let w2 = triangle_words[w + 8u - (packet_lane & 4u)];
            let p0 = vec3<f32>(bitcast<f32>(subgroupBroadcast(w01, 0u)), bitcast<f32>(subgroupBroadcast(w01, 1u)), bitcast<f32>(subgroupBroadcast(w01, 2u)));
            let p1 = vec3<f32>(bitcast<f32>(subgroupBroadcast(w01, 4u)), bitcast<f32>(subgroupBroadcast(w01, 5u)), bitcast<f32>(subgroupBroadcast(w01, 6u)));
            let p2 = vec3<f32>(bitcast<f32>(subgroupBroadcast(w2, 0u)), bitcast<f32>(subgroupBroadcast(w2, 1u)), bitcast<f32>(subgroupBroadcast(w2, 2u)));
            let h = corners_tuv(ray, p0, p1, p2, t_min, t_best);
            if h.w != 0.0 {
                t_best = h.x;
                best = k;
                best_tuv = h.xyz;
            }
        }
        current = PACKET_NONE;
    }
    if best == NO_HIT {
        return no_hit();
    }
    mesh_triangle = best;
    return triangle_hit(best, best_tuv);
}

// trace_each as a packet walk of the top-level tree; mesh instances are
// walked by packet_mesh, other shapes by each lane on its own. With
// `any_hit`, a lane that has found a hit stops asking for nodes (its
// interval becomes empty) and the walk ends when every lane has one.
fn trace_packet(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    var best: TraceHit;
    best.t = t_max;
    best.instance = NO_HIT;
    var object_normal = vec3<f32>(0.0);
    var object_geometric = vec3<f32>(0.0);
    let inv_d = 1.0 / d;
    var sp = 0u;
    let r = packet_load_node(0u);
    let rs = box_span(r.lo, r.hi, o, inv_d, t_min, t_max);
    var current = select(PACKET_NONE, r.node, subgroupAny(rs.x <= rs.y));
    // The far end of this lane's interval: -1 once an any-hit lane is done.
    var t_far = t_max;
    loop {
        if current == PACKET_NONE {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !packet_step() {
            break;
        }
        let first = current & 0x1fffffffu;
        let count = current >> 29u;
        if count == 0u {
            current = packet_descend(first, o, inv_d, t_min, t_far, &sp);
            continue;
        }
        for (var k = first; k < first + count; k++) {
            let inst = tlas_items[k];
            let shape = load_instance(inst).shape;
            let s = load_shape(shape);
            if skip_meshes && s.kind == SHAPE_MESH {
                continue;
            }
            let m = packet_object_from_world(inst);
            let ol = (m * vec4<f32>(o, 1.0)).xyz;
            let dl = (m * vec4<f32>(d, 0.0)).xyz;
            var h: ObjectHit;
            if MESHES_ENABLED && s.kind == SHAPE_MESH {
                h = packet_mesh(s.blas_root, ol, dl, t_min, t_far, sp);
            } else {
                h = intersect_instance_shape(shape, ol, dl, t_min, t_far, sp);
            }
            if CSG_ENABLED && s.kind == SHAPE_CSG {
                packet_steps = subgroupMin(steps_left);
            }
            if h.hit {
                best.t = h.t;
                best.instance = inst;
                best.material = select(object_material, load_instance(inst).material, object_material == CSG_NO_MATERIAL);
                object_normal = h.normal;
                object_geometric = h.geometric;
                hit_triangle = mesh_triangle;
                t_far = select(h.t, -1.0, any_hit);
            }
        }
        if any_hit && subgroupAll(best.instance != NO_HIT) {
            break;
        }
        current = PACKET_NONE;
    }
    if best.instance != NO_HIT && !any_hit {
        let to_world = load_instance(best.instance).normal_from_object;
        best.normal = normalize((to_world * vec4<f32>(object_normal, 0.0)).xyz);
        best.geometric = normalize((to_world * vec4<f32>(object_geometric, 0.0)).xyz);
    }
    return best;
}

// The closest or any hit of the world ray (o, d) in (t_min, t_max), every
// invocation of the subgroup making the call together: the packet walk.
fn trace_converged(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    packet_lane = subgroupExclusiveAdd(1u);
    packet_steps = subgroupMin(steps_left);
    return trace_packet(o, d, t_min, t_max, skip_meshes, any_hit);
}

// trace_converged for the invocations where `wants` holds, the others
// getting a miss: one packet
// walk, which the others join with an empty interval (they ask for no
// node), and none where no invocation wants one.
fn trace_masked(wants: bool, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    if !subgroupAny(wants) {
        return trace_miss(t_max);
    }
    var hit = trace_converged(o, d, t_min, select(-1.0, t_max, wants), skip_meshes, any_hit);
    if !wants {
        hit.t = t_max;
    }
    return hit;
}

// Whether `b` holds for any invocation of the subgroup.
fn any_lane(b: bool) -> bool {
    return subgroupAny(b);
}
