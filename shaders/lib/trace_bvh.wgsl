// The top-level trace through celray's own two-level BVH (software
// traversal). Included by lib/traverse.wgsl, whose helpers it uses.

// The closest hit of the world ray (o, d) in (t_min, t_max). With
// `any_hit`, returns the first hit found (shadow rays). With `skip_meshes`,
// triangle meshes are ignored (hybrid mode rasterizes them).
fn trace(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    var best: TraceHit;
    best.t = t_max;
    best.instance = NO_HIT;
    var object_normal = vec3<f32>(0.0);
    var object_geometric = vec3<f32>(0.0);
    let inv_d = 1.0 / d;
    var sp = 0u;
    var current = select(NO_HIT, 0u, box_entry(0u, o, inv_d, t_min, t_max, true) < 3.0e38);
    loop {
        if current == NO_HIT {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !take_step() {
            break;
        }
        let node = load_tree_node(current, true);
        if node.count == 0u {
            current = descend(node, o, inv_d, t_min, best.t, &sp, true);
            continue;
        }
        for (var k = node.left_or_first; k < node.left_or_first + node.count; k++) {
            let inst = tlas_items[k];
            let shape = load_instance(inst).shape;
            if skip_meshes && load_shape(shape).kind == SHAPE_MESH {
                continue;
            }
            let m = load_instance(inst).object_from_world;
            let h = intersect_instance_shape(shape, (m * vec4<f32>(o, 1.0)).xyz, (m * vec4<f32>(d, 0.0)).xyz, t_min, best.t, sp);
            if h.hit {
                best.t = h.t;
                best.instance = inst;
                best.material = select(object_material, load_instance(inst).material, object_material == CSG_NO_MATERIAL);
                object_normal = h.normal;
                object_geometric = h.geometric;
                hit_triangle = mesh_triangle;
                if any_hit {
                    return best;
                }
            }
        }
        current = NO_HIT;
    }
    if best.instance != NO_HIT {
        let to_world = load_instance(best.instance).normal_from_object;
        best.normal = normalize((to_world * vec4<f32>(object_normal, 0.0)).xyz);
        best.geometric = normalize((to_world * vec4<f32>(object_geometric, 0.0)).xyz);
    }
    return best;
}
