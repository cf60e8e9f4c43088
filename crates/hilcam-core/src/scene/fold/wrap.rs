//! Folds applied to the faces of a mesh, by material (wrinkled MLI at scene load).
//!
//! 1. Vertices are welded by exact position, so meshes split per material (as tobj
//!    returns them) still know which faces touch.
//! 2. Selected triangles are grouped by plane (normal and offset, quantised). Each plane
//!    gets its own 2-D chart (an orthonormal basis of its normal) and its own fold field
//!    (seed mixed with the plane), so the folds on one flat panel are one continuous field.
//! 3. Every edge gets `ceil(length / edge_m)` segments, a function of the edge alone, so
//!    both triangles sharing it agree. A triangle is cut into a regular N-grid (N = its
//!    largest edge count) whose boundary points are snapped to their edge's segments;
//!    collapsed sub-triangles are dropped. The result is conforming: no T-junctions
//!    between selected triangles.
//! 4. Each new vertex moves along its plane normal by the field height. Vertices on
//!    *pinned* edges stay put: edges shared with an unselected face, and edges between
//!    selected faces that are not coplanar (box corners); so do original vertices that
//!    an unselected face or a second plane touches (vertex-only contacts). The height
//!    fades in with a smoothstep over `TAPER_WIDTHS`·width from the plane's pinned
//!    edges, so folds do not end in a wall. Hence: no cracks anywhere, flat seams at corners. A curved
//!    (faceted) selected region folds inside each facet only, since all its edges are
//!    pinned. Pinned edges shared with an unselected face keep their subdivision points
//!    on the straight edge (T-junctions there are geometrically closed up to f32 rounding).

use super::field::{FoldField, FoldParams};
use crate::render::geometry::TriMesh;
use crate::render::sampling::{ShadingBasis, mix64};
use glam::{DVec2, DVec3, Vec3};
use std::collections::HashMap;

/// Fade-in distance from pinned edges, in crease half-widths.
pub const TAPER_WIDTHS: f64 = 2.0;
/// Groups with more pinned edges than this skip the taper (hard pin), to bound cost.
const MAX_TAPER_EDGES: usize = 512;

/// Most triangles one wrap may produce (~1 GB of mesh and tree). [`wrap_triangle_estimate`]
/// is checked against it before anything is subdivided.
pub const MAX_WRAP_TRIANGLES: u64 = 10_000_000;

/// How many triangles wrapping the faces of `materials` at `edge_m` would give, without
/// subdividing: each selected face becomes N² (N: its longest edge's segment count), the
/// rest stay one. An upper bound (snapping drops a few); f64, so a tiny or zero `edge_m`
/// gives a huge or infinite count rather than overflowing, and NaN for a NaN `edge_m`.
pub fn wrap_triangle_estimate(mesh: &TriMesh, materials: &[u32], edge_m: f32) -> f64 {
    let e = f64::from(edge_m);
    mesh.indices
        .iter()
        .zip(&mesh.material)
        .map(|(t, m)| {
            if !materials.contains(m) {
                return 1.0;
            }
            let p = t.map(|v| mesh.positions[v as usize].as_dvec3());
            let longest = p[0].distance(p[1]).max(p[1].distance(p[2])).max(p[2].distance(p[0]));
            let n = (longest / e).ceil().max(1.0);
            n * n
        })
        .sum()
}

/// What `wrap_faces_report` did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WrapReport {
    pub selected_triangles: usize,
    pub output_triangles: usize,
    pub planes: usize,
    pub pinned_edges: usize,
    /// Sub-triangles collapsed by edge snapping (dropped, zero area).
    pub collapsed: usize,
    /// Planes whose taper was skipped because they had too many pinned edges.
    pub untapered_planes: usize,
}

/// Fold every triangle whose material is in `materials`; see the module doc.
///
/// `edge_m` is the target edge length of the subdivision (m); the fold field is
/// `params` with `seed`. Unselected triangles are copied unchanged.
pub fn wrap_faces(mesh: &TriMesh, materials: &[u32], params: &FoldParams, seed: u64, edge_m: f32) -> TriMesh {
    wrap_faces_report(mesh, materials, params, seed, edge_m).0
}

struct Plane {
    normal: DVec3,
    frame: ShadingBasis,
    field: FoldField,
    /// Pinned edges (flat positions) of this plane, for the taper.
    pinned: Vec<(DVec3, DVec3)>,
}

/// [`wrap_faces`] plus counters. Invalid `params` or `edge_m` leave the mesh unchanged
/// (logged), since a scene can still render unfolded.
pub fn wrap_faces_report(
    mesh: &TriMesh,
    materials: &[u32],
    params: &FoldParams,
    seed: u64,
    edge_m: f32,
) -> (TriMesh, WrapReport) {
    let mut report = WrapReport::default();
    if let Err(e) = params.validate() {
        tracing::error!(%e, "wrap: invalid fold parameters, mesh left unfolded");
        return (mesh.clone(), report);
    }
    if !(edge_m.is_finite() && edge_m > 0.0) {
        tracing::error!(edge_m, "wrap: edge_m must be > 0, mesh left unfolded");
        return (mesh.clone(), report);
    }
    let would_make = wrap_triangle_estimate(mesh, materials, edge_m);
    if would_make > MAX_WRAP_TRIANGLES as f64 {
        tracing::error!(edge_m, would_make, limit = MAX_WRAP_TRIANGLES, "wrap: too many triangles, mesh left unfolded");
        return (mesh.clone(), report);
    }
    let selected: Vec<bool> = mesh.material.iter().map(|m| materials.contains(m)).collect();
    report.selected_triangles = selected.iter().filter(|&&s| s).count();

    let welded = Welded::new(mesh);
    let (plane_of, mut planes) = group_planes(&welded, &selected, params, seed);
    report.planes = planes.len();
    let topo = Topology::new(welded, plane_of, &selected, &mut planes, &mut report);
    let out = subdivide(&topo, &planes, params, edge_m, &mut report);
    let out = compact(out);
    report.output_triangles = out.indices.len();
    tracing::debug!(?report, "wrap done");
    (out, report)
}

/// Step 1: the mesh with its vertices welded by exact position.
struct Welded<'m> {
    mesh: &'m TriMesh,
    /// Each vertex's first vertex at the same position.
    canon: Vec<u32>,
}

impl<'m> Welded<'m> {
    fn new(mesh: &'m TriMesh) -> Self {
        let mut by_pos: HashMap<[u32; 3], u32> = HashMap::new();
        let canon = mesh
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| *by_pos.entry(p.to_array().map(f32::to_bits)).or_insert(i as u32))
            .collect();
        Welded { mesh, canon }
    }

    fn tri(&self, t: usize) -> [u32; 3] {
        self.mesh.indices[t].map(|v| self.canon[v as usize])
    }

    fn pos(&self, v: u32) -> DVec3 {
        self.mesh.positions[v as usize].as_dvec3()
    }
}

/// Step 2: the planes of the selected triangles (each triangle's, `None` for unselected
/// or degenerate ones), each with its chart and fold field.
fn group_planes(w: &Welded, selected: &[bool], params: &FoldParams, seed: u64) -> (Vec<Option<usize>>, Vec<Plane>) {
    let mut plane_of: Vec<Option<usize>> = vec![None; w.mesh.indices.len()];
    let mut planes: Vec<Plane> = Vec::new();
    let mut plane_key: HashMap<[i64; 4], usize> = HashMap::new();
    for t in 0..w.mesh.indices.len() {
        if !selected[t] {
            continue;
        }
        let [a, b, c] = w.tri(t).map(|v| w.pos(v));
        let n = (b - a).cross(c - a);
        if n.length() <= 0.0 || !n.is_finite() {
            continue; // degenerate: copied through below
        }
        let n = n.normalize();
        let key = [
            (n.x * 1e5).round() as i64,
            (n.y * 1e5).round() as i64,
            (n.z * 1e5).round() as i64,
            (n.dot(a) * 1e4).round() as i64,
        ];
        let id = *plane_key.entry(key).or_insert_with(|| {
            let h = key.iter().fold(seed, |h, &k| mix64(h ^ k as u64));
            // Chart and displacement from the quantised normal: independent of which
            // triangle comes first and free of −0.0 (which flips `ShadingBasis::from_normal`).
            let nq = (DVec3::new(key[0] as f64, key[1] as f64, key[2] as f64) * 1e-5).normalize() + DVec3::ZERO;
            let frame = ShadingBasis::from_normal(nq.as_vec3());
            planes.push(Plane {
                normal: nq,
                frame,
                field: FoldField::new(*params, h).expect("validated above"),
                pinned: Vec::new(),
            });
            planes.len() - 1
        });
        plane_of[t] = Some(id);
    }
    (plane_of, planes)
}

/// Which (welded) edges and vertices stay put.
struct Topology<'m> {
    welded: Welded<'m>,
    plane_of: Vec<Option<usize>>,
    /// Which triangles touch each (welded) edge, (low, high).
    edge_tris: HashMap<(u32, u32), Vec<usize>>,
    pinned_vertex: HashMap<u32, bool>,
}

impl<'m> Topology<'m> {
    /// Pins the edges that are not free (filling each plane's pinned list for its taper)
    /// and the vertices an unselected triangle or a second plane touches.
    fn new(
        welded: Welded<'m>,
        plane_of: Vec<Option<usize>>,
        selected: &[bool],
        planes: &mut [Plane],
        report: &mut WrapReport,
    ) -> Self {
        let mut edge_tris: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
        for t in 0..welded.mesh.indices.len() {
            let v = welded.tri(t);
            for e in 0..3 {
                let (p, q) = (v[e], v[(e + 1) % 3]);
                edge_tris.entry((p.min(q), p.max(q))).or_default().push(t);
            }
        }
        let mut topo = Topology { welded, plane_of, edge_tris, pinned_vertex: HashMap::new() };
        let mut pinned_edges: Vec<(u32, u32)> = topo.edge_tris.keys().copied().filter(|e| !topo.edge_free(e)).collect();
        pinned_edges.sort_unstable(); // deterministic order for the taper lists
        for &(p, q) in &pinned_edges {
            topo.pinned_vertex.insert(p, true);
            topo.pinned_vertex.insert(q, true);
            let mut ps: Vec<usize> = topo.edge_tris[&(p, q)].iter().filter_map(|&t| topo.plane_of[t]).collect();
            ps.dedup();
            for id in ps {
                planes[id].pinned.push((topo.welded.pos(p), topo.welded.pos(q)));
            }
        }
        // Vertices touched by an unselected triangle, or by two planes, stay put as well.
        let mut vertex_plane: HashMap<u32, Option<usize>> = HashMap::new();
        for (t, &pl) in topo.plane_of.iter().enumerate() {
            for v in topo.welded.tri(t) {
                let prev = *vertex_plane.entry(v).or_insert(pl);
                if pl.is_none() || prev != pl {
                    topo.pinned_vertex.insert(v, true);
                }
            }
        }
        report.pinned_edges = pinned_edges.iter().filter(|e| topo.edge_tris[e].iter().any(|&t| selected[t])).count();
        for p in planes.iter_mut() {
            p.pinned.dedup();
            if p.pinned.len() > MAX_TAPER_EDGES {
                report.untapered_planes += 1;
            }
        }
        if report.untapered_planes > 0 {
            tracing::warn!(
                planes = report.untapered_planes,
                "wrap: planes with too many pinned edges fold without taper"
            );
        }
        topo
    }

    /// An edge of a selected triangle is free when every triangle on it is selected and
    /// in the same plane (an open boundary edge, used once, is free too).
    fn edge_free(&self, e: &(u32, u32)) -> bool {
        let ts = &self.edge_tris[e];
        let p0 = self.plane_of[ts[0]];
        p0.is_some() && ts.iter().all(|&t| self.plane_of[t] == p0)
    }
}

/// Steps 3–4: cut each selected triangle into its grid and move the new vertices along their
/// plane's normal; unselected triangles are copied.
fn subdivide(topo: &Topology, planes: &[Plane], params: &FoldParams, edge_m: f32, report: &mut WrapReport) -> TriMesh {
    let (mesh, w) = (topo.welded.mesh, &topo.welded);
    let pos = |v: u32| w.pos(v);
    let mut out = TriMesh { positions: mesh.positions.clone(), indices: Vec::new(), material: Vec::new() };
    let mut vkey: HashMap<VKey, u32> = HashMap::new();
    let taper_len = TAPER_WIDTHS * params.width_m;
    let seg = |p: u32, q: u32| ((pos(p).distance(pos(q)) / f64::from(edge_m)).ceil() as u32).max(1);
    for (t, &pl) in topo.plane_of.iter().enumerate() {
        let Some(pid) = pl else {
            out.indices.push(mesh.indices[t]);
            out.material.push(mesh.material[t]);
            continue;
        };
        let plane = &planes[pid];
        let v = w.tri(t);
        let counts = [seg(v[0], v[1]), seg(v[1], v[2]), seg(v[2], v[0])];
        let n_grid = counts.iter().copied().max().unwrap_or(1);
        let corners = v.map(pos);
        // Grid point (i, j) ↦ barycentric (1 − (i+j)/N, i/N, j/N) on (v0, v1, v2).
        let mut grid_vertex = |i: u32, j: u32, out: &mut TriMesh| -> u32 {
            let key = grid_key(v, counts, n_grid, i, j);
            if let Some(&id) = vkey.get(&key) {
                return id;
            }
            let (p, pinned) = match key {
                VKey::Corner(c) => (pos(c), *topo.pinned_vertex.get(&c).unwrap_or(&false)),
                VKey::Edge(a, b, k, n) => {
                    let s = f64::from(k) / f64::from(n);
                    (pos(a) * (1.0 - s) + pos(b) * s, !topo.edge_free(&(a, b)))
                }
                VKey::Inner(..) => {
                    let (u, w) = (f64::from(i) / f64::from(n_grid), f64::from(j) / f64::from(n_grid));
                    (corners[0] * (1.0 - u - w) + corners[1] * u + corners[2] * w, false)
                }
            };
            let h = if pinned { 0.0 } else { height(plane, p, taper_len) };
            let id = match (key, pinned) {
                (VKey::Corner(c), true) => c, // unmoved: share with unselected neighbours
                _ => {
                    out.positions.push((p + plane.normal * h).as_vec3());
                    out.positions.len() as u32 - 1
                }
            };
            vkey.insert(key, id);
            id
        };
        for j in 0..n_grid {
            for i in 0..n_grid - j {
                let a = grid_vertex(i, j, &mut out);
                let b = grid_vertex(i + 1, j, &mut out);
                let c = grid_vertex(i, j + 1, &mut out);
                push_tri(&mut out, [a, b, c], mesh.material[t], report);
                if i + j + 1 < n_grid {
                    let d = grid_vertex(i + 1, j + 1, &mut out);
                    push_tri(&mut out, [b, d, c], mesh.material[t], report);
                }
            }
        }
    }
    out
}

fn push_tri(out: &mut TriMesh, t: [u32; 3], material: u32, report: &mut WrapReport) {
    if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
        report.collapsed += 1;
    } else {
        out.indices.push(t);
        out.material.push(material);
    }
}

/// Identity of a subdivision vertex: an original (welded) vertex, the k-th of n points on
/// an edge (a < b, k counted from a), or an interior grid point of one triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum VKey {
    Corner(u32),
    Edge(u32, u32, u32, u32),
    Inner([u32; 3], u32, u32),
}

/// Key of grid point (i, j) of the triangle `v` with N = `n`: boundary points snap to
/// their edge's `counts`, rounding ties toward the nearer corner (so corner sub-triangles
/// collapse instead of folding over).
fn grid_key(v: [u32; 3], counts: [u32; 3], n: u32, i: u32, j: u32) -> VKey {
    let l0 = n - i - j; // weight of v0
    // Position along edge (from, to) at fine index f of n, snapped to `c` segments.
    let on_edge = |from: u32, to: u32, f: u32, c: u32| {
        let k = if 2 * f <= n {
            (f64::from(f) * f64::from(c) / f64::from(n) - 0.5).ceil() as u32
        } else {
            c - (f64::from(n - f) * f64::from(c) / f64::from(n) - 0.5).ceil() as u32
        };
        let (a, b, k) = if from < to { (from, to, k) } else { (to, from, c - k) };
        if k == 0 {
            VKey::Corner(a)
        } else if k == c {
            VKey::Corner(b)
        } else {
            VKey::Edge(a, b, k, c)
        }
    };
    match (l0, i, j) {
        (_, 0, 0) => VKey::Corner(v[0]),
        (0, _, 0) => VKey::Corner(v[1]),
        (0, 0, _) => VKey::Corner(v[2]),
        (_, _, 0) => on_edge(v[0], v[1], i, counts[0]),
        (0, _, _) => on_edge(v[1], v[2], j, counts[1]),
        (_, 0, _) => on_edge(v[2], v[0], l0, counts[2]),
        _ => VKey::Inner(v, i, j),
    }
}

/// Field height at flat point `p` of a plane, faded near its pinned edges.
fn height(plane: &Plane, p: DVec3, taper_len: f64) -> f64 {
    let q = p.as_vec3();
    let uv = DVec2::new(f64::from(q.dot(plane.frame.t)), f64::from(q.dot(plane.frame.b)));
    let h = plane.field.height(uv);
    if h == 0.0 || plane.pinned.len() > MAX_TAPER_EDGES {
        return h;
    }
    let d = plane.pinned.iter().map(|&(a, b)| segment_distance(p, a, b)).fold(f64::INFINITY, f64::min);
    let x = (d / taper_len).min(1.0);
    h * x * x * (3.0 - 2.0 * x)
}

fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let s = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    p.distance(a + ab * s)
}

/// Drop vertices no triangle uses, keeping the order of the rest.
fn compact(mesh: TriMesh) -> TriMesh {
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    for t in &mesh.indices {
        for &v in t {
            remap[v as usize] = 0;
        }
    }
    let mut positions: Vec<Vec3> = Vec::new();
    for (i, r) in remap.iter_mut().enumerate() {
        if *r == 0 {
            *r = positions.len() as u32;
            positions.push(mesh.positions[i]);
        }
    }
    let indices = mesh.indices.iter().map(|t| t.map(|v| remap[v as usize])).collect();
    TriMesh { positions, indices, material: mesh.material }
}
