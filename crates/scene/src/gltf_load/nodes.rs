//! The node hierarchy: parents checked (one parent per node, no cycles), the scene's roots, and
//! each node's local transform (a matrix, or TRS with a unit-length rotation).

use glam::{DAffine3, DQuat, Vec3};
use gltf::json;

use super::doc::Doc;
use super::Ctx;
use crate::error::SceneError;

/// Checks node references and that the hierarchy is a forest; returns each node's parent.
pub(super) fn check_hierarchy(doc: &Doc, ctx: &Ctx) -> Result<Vec<Option<usize>>, SceneError> {
    let n = doc.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (i, node) in doc.nodes.iter().enumerate() {
        if let Some(m) = node.mesh {
            if m.value() >= doc.meshes.len() {
                return Err(ctx.unresolved(
                    format!("/nodes/{i}/mesh"),
                    "/meshes",
                    m.value(),
                    doc.meshes.len(),
                ));
            }
        }
        for (j, c) in node.children.iter().flatten().enumerate() {
            let c = c.value();
            let p = format!("/nodes/{i}/children/{j}");
            if c >= n {
                return Err(ctx.unresolved(p, "/nodes", c, n));
            }
            if let Some(other) = parent[c] {
                return Err(ctx.hierarchy(p, format!("node {c} already has parent {other}")));
            }
            parent[c] = Some(i);
        }
    }
    // With at most one parent each, a loop is a parent chain that comes back to itself.
    // 0 = unvisited, 1 = on the current chain, 2 = known to reach a root.
    let mut state = vec![0u8; n];
    let mut chain = Vec::new();
    for start in 0..n {
        let mut cur = Some(start);
        while let Some(i) = cur {
            match state[i] {
                2 => break,
                1 => {
                    return Err(ctx.hierarchy(
                        format!("/nodes/{i}"),
                        "the node is its own ancestor (a loop)".into(),
                    ))
                }
                _ => {
                    state[i] = 1;
                    chain.push(i);
                    cur = parent[i];
                }
            }
        }
        for i in chain.drain(..) {
            state[i] = 2;
        }
    }
    Ok(parent)
}

/// The root nodes to draw: the default scene's, scene 0's, or every root node if there is no
/// scene at all (glTF leaves that case to the application).
pub(super) fn scene_roots(
    doc: &Doc,
    parent: &[Option<usize>],
    ctx: &Ctx,
) -> Result<Vec<usize>, SceneError> {
    for (s, scene) in doc.scenes.iter().enumerate() {
        let Some(nodes) = &scene.nodes else { continue };
        if nodes.is_empty() {
            return Err(ctx.invalid(format!("/scenes/{s}/nodes"), "empty array".into()));
        }
        let mut listed = vec![false; doc.nodes.len()];
        for (j, &node) in nodes.iter().enumerate() {
            let i = node as usize;
            let p = format!("/scenes/{s}/nodes/{j}");
            if i >= doc.nodes.len() {
                return Err(ctx.unresolved(p, "/nodes", i, doc.nodes.len()));
            }
            // A root listed twice would be drawn twice (and a long list of one big subtree
            // would multiply the instance count): the schema's uniqueItems.
            if std::mem::replace(&mut listed[i], true) {
                return Err(ctx.invalid(p, format!("node {i} is listed twice")));
            }
            if let Some(par) = parent[i] {
                return Err(ctx.invalid(
                    p,
                    format!("node {i} is not a root node (its parent is {par})"),
                ));
            }
        }
    }
    let selected = match doc.scene {
        Some(s) => {
            let s = usize::try_from(s).unwrap_or(usize::MAX);
            if s >= doc.scenes.len() {
                return Err(ctx.unresolved("/scene".into(), "/scenes", s, doc.scenes.len()));
            }
            Some(s)
        }
        None if !doc.scenes.is_empty() => Some(0),
        None => None,
    };
    Ok(match selected {
        Some(s) => doc.scenes[s]
            .nodes
            .iter()
            .flatten()
            .map(|&n| n as usize)
            .collect(),
        None => {
            log::info!("{}: no scene defined; drawing every root node", ctx.file);
            (0..doc.nodes.len())
                .filter(|&i| parent[i].is_none())
                .collect()
        }
    })
}

pub(super) fn local_transform(
    node: &json::Node,
    i: usize,
    ctx: &Ctx,
) -> Result<DAffine3, SceneError> {
    let p = format!("/nodes/{i}");
    let has_trs = node.translation.is_some() || node.rotation.is_some() || node.scale.is_some();
    if let Some(m) = node.matrix {
        if has_trs {
            return Err(ctx.invalid(
                format!("{p}/matrix"),
                "both a matrix and translation/rotation/scale".into(),
            ));
        }
        if !m.iter().all(|x| x.is_finite()) {
            return Err(ctx.non_finite(format!("{p}/matrix"), format!("{m:?}")));
        }
        // Column-major; the bottom row must be (0, 0, 0, 1) for an affine transform.
        if m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
            return Err(ctx.invalid(
                format!("{p}/matrix"),
                "not an affine transform (bottom row is not 0, 0, 0, 1)".into(),
            ));
        }
        let d = |k: usize| f64::from(m[k]);
        return Ok(DAffine3::from_cols_array(&[
            d(0),
            d(1),
            d(2),
            d(4),
            d(5),
            d(6),
            d(8),
            d(9),
            d(10),
            d(12),
            d(13),
            d(14),
        ]));
    }
    let t = node.translation.unwrap_or([0.0; 3]);
    if !t.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/translation"), format!("{t:?}")));
    }
    let s = node.scale.unwrap_or([1.0; 3]);
    if !s.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/scale"), format!("{s:?}")));
    }
    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
    if !r.iter().all(|x| x.is_finite()) {
        return Err(ctx.non_finite(format!("{p}/rotation"), format!("{r:?}")));
    }
    let q = DQuat::from_xyzw(
        f64::from(r[0]),
        f64::from(r[1]),
        f64::from(r[2]),
        f64::from(r[3]),
    );
    let len = q.length();
    // Exporters write quaternions rounded to f32 text; accept those, renormalised.
    if (len - 1.0).abs() > 1e-3 {
        return Err(ctx.invalid(
            format!("{p}/rotation"),
            format!("not a unit quaternion (length {len})"),
        ));
    }
    Ok(DAffine3::from_scale_rotation_translation(
        Vec3::from_array(s).as_dvec3(),
        q / len,
        Vec3::from_array(t).as_dvec3(),
    ))
}
