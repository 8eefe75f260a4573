//! The tissue surface as the needle sees it: the surface triangles with the entry and
//! exit splits (the touched triangle split 1-to-3 around the Surface or Exit node,
//! [`crate::puncture::split_triangle`]), the triangle grid kept in step with them, and the
//! queries on it: where the tip's swept segment crosses the surface (entering against the
//! outward normal, or leaving along it), and whether a point is inside the rest body.

use crate::puncture::{restore_triangle, split_triangle, Split};
use crate::surface_query::{first_crossing, segment_triangle, Side, TriangleGrid};
use glam::DVec3;
use needlesim_core::{Backend, NodeField, SimError};

/// Surface triangles, their grid and the split stack (entry split, then exit split).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct SurfaceSplits {
    triangles: Vec<[u32; 3]>,
    grid: TriangleGrid,
    splits: Vec<Split>,
}

impl SurfaceSplits {
    /// The unsplit surface `triangles` over the rest positions `rest`, binned with a margin
    /// of `margin` m.
    pub fn new(triangles: Vec<[u32; 3]>, rest: &[[f64; 3]], margin: f64) -> SurfaceSplits {
        let grid = TriangleGrid::build(rest, &triangles, margin);
        SurfaceSplits {
            triangles,
            grid,
            splits: Vec::new(),
        }
    }

    /// Surface triangles (node indices), with the splits.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The latest split.
    pub fn last_split(&self) -> Option<&Split> {
        self.splits.last()
    }

    /// Whether the splits and triangles name only nodes below `n_active` (a restored
    /// checkpoint).
    pub fn fits(&self, n_active: usize) -> bool {
        self.splits.len() <= 2
            && self
                .triangles
                .iter()
                .flatten()
                .all(|&i| (i as usize) < n_active)
    }

    /// Splits triangle `id` around node `node`; `rest` gives a node's rest position.
    pub fn split(&mut self, id: usize, node: u32, rest: impl Fn(u32) -> [f64; 3]) {
        let sp = split_triangle(&mut self.triangles, id, node);
        self.grid.remove(id as u32);
        for tid in [id, sp.appended_at, sp.appended_at + 1] {
            let c = self.triangles[tid].map(&rest);
            self.grid.insert(tid as u32, c);
        }
        self.splits.push(sp);
    }

    /// Undoes the latest split, if any.
    pub fn unsplit(&mut self, rest: impl Fn(u32) -> [f64; 3]) {
        let Some(sp) = self.splits.pop() else {
            return;
        };
        for id in [sp.triangle, sp.appended_at, sp.appended_at + 1] {
            self.grid.remove(id as u32);
        }
        restore_triangle(&mut self.triangles, &sp);
        let corners = sp.original.map(rest);
        self.grid.insert(sp.triangle as u32, corners);
    }

    /// The first surface triangle crossed by the segment `p0 -> p1` on the deformed
    /// surface (corners read from `backend`), from outside (`entering`, against the
    /// outward normal of the counter-clockwise winding) or from inside, and where.
    /// Triangles with a corner in `skip` (the needle nodes) are ignored; `rest` gives a
    /// node's rest position ([`SurfaceSplits::crossing_query`]).
    pub fn crossing(
        &self,
        backend: &mut dyn Backend,
        (p0, p1): ([f64; 3], [f64; 3]),
        entering: bool,
        skip: &[u32],
        rest: &dyn Fn(u32) -> Option<[f64; 3]>,
    ) -> Result<Option<(usize, [f64; 3])>, SimError> {
        let Some(query) = self.crossing_query(p0, p1, entering, skip, rest) else {
            return Ok(None);
        };
        let mut pos = vec![[0.0f32; 4]; query.corners.len()];
        backend.read_nodes(NodeField::Position, &query.corners, &mut pos)?;
        Ok(self.crossing_at(&query, &pos))
    }

    /// The first half of [`SurfaceSplits::crossing`]: the candidate triangles and the
    /// corners to read (`None`: no candidate, so no crossing). The caller reads the
    /// corners' positions (with other reads) and gives them to
    /// [`SurfaceSplits::crossing_at`] while the triangles and `skip` are unchanged.
    ///
    /// The grid's cells give the triangles whose rest boxes, inflated by the grid's
    /// margin (how far the surface may have moved), may meet the segment's box, and
    /// more: whole cells of them, which reach up to a few cells farther. Those whose
    /// corners all have a rest position (`rest` gives one for a mesh node, `None` for a
    /// needle node) and whose rest box inflated by the margin plus one cell misses the
    /// segment's are dropped, so a needle well inside the body no longer reads the entry
    /// face's corners every step. What the cells alone were sure to find was the margin's
    /// reach (more by up to two cells, depending on where the cell boundaries fell); the
    /// extra cell keeps some of that slack, as nothing enforces the margin (a surface
    /// tenting out before the tip leaves may move farther).
    pub fn crossing_query(
        &self,
        p0: [f64; 3],
        p1: [f64; 3],
        entering: bool,
        skip: &[u32],
        rest: &dyn Fn(u32) -> Option<[f64; 3]>,
    ) -> Option<CrossingQuery> {
        if p0 == p1 {
            return None;
        }
        let (lo, hi) = (
            DVec3::from(p0).min(p1.into()),
            DVec3::from(p0).max(p1.into()),
        );
        let margin = self.grid.margin() + self.grid.cell();
        let within = |t: &[u32; 3]| {
            let corners: Option<Vec<DVec3>> = t.iter().map(|&v| rest(v).map(DVec3::from)).collect();
            corners.is_none_or(|c| {
                let tlo = c.iter().fold(DVec3::INFINITY, |a, &p| a.min(p)) - margin;
                let thi = c.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p)) + margin;
                tlo.cmple(hi).all() && lo.cmple(thi).all()
            })
        };
        let mut cand = self.grid.candidates(p0, p1);
        cand.retain(|&c| {
            let t = &self.triangles[c as usize];
            !t.iter().any(|v| skip.contains(v)) && within(t)
        });
        if cand.is_empty() {
            return None;
        }
        let mut corners: Vec<u32> = cand
            .iter()
            .flat_map(|&c| self.triangles[c as usize])
            .collect();
        corners.sort_unstable();
        corners.dedup();
        Some(CrossingQuery {
            p0,
            p1,
            entering,
            candidates: cand,
            corners,
        })
    }

    /// The answer of [`SurfaceSplits::crossing`] from the corner positions `pos` of
    /// `query` (in the order of [`CrossingQuery::corners`]).
    pub fn crossing_at(
        &self,
        query: &CrossingQuery,
        pos: &[[f32; 4]],
    ) -> Option<(usize, [f64; 3])> {
        let corners = &query.corners;
        let p = |v: u32| {
            let q = pos[corners.binary_search(&v).expect("listed")];
            [q[0] as f64, q[1] as f64, q[2] as f64]
        };
        let side = if query.entering {
            Side::Entering
        } else {
            Side::Leaving
        };
        let hit = first_crossing(
            query.p0,
            query.p1,
            query.candidates.iter().copied(),
            side,
            |c| self.triangles[c as usize].map(p),
        );
        hit.map(|h| (h.triangle as usize, h.point))
    }
}

/// A surface crossing query whose corner positions are still to be read
/// ([`SurfaceSplits::crossing_query`]).
#[derive(Debug, Clone)]
pub(crate) struct CrossingQuery {
    p0: [f64; 3],
    p1: [f64; 3],
    entering: bool,
    candidates: Vec<u32>,
    /// Corner nodes of the candidate triangles, sorted, each once.
    pub corners: Vec<u32>,
}

/// Segment parameters in `[0, 1]` where `p0 -> p1` crosses the surface `triangles` over
/// `rest` (a crossing on an edge is found in both triangles sharing it).
pub(crate) fn rest_crossings(
    rest: &[[f64; 3]],
    triangles: &[[u32; 3]],
    p0: [f64; 3],
    p1: [f64; 3],
) -> Vec<f64> {
    triangles
        .iter()
        .filter_map(|t| {
            let [a, b, c] = t.map(|v| rest[v as usize]);
            segment_triangle(p0, p1, a, b, c).map(|h| h.0)
        })
        .collect()
}

/// Whether each of `points` is inside the closed rest surface `triangles` over `rest` (outward,
/// counter-clockwise winding): parry's point query on the oriented triangle mesh, which
/// decides by the pseudo-normal of the closest feature (face, edge or vertex) and so has
/// none of the edge-grazing cases of a ray-parity test.
pub(crate) fn inside_rest_body(
    rest: &[[f64; 3]],
    triangles: &[[u32; 3]],
    points: &[[f64; 3]],
) -> Vec<bool> {
    use parry3d_f64::math::Vector;
    use parry3d_f64::query::PointQueryWithLocation;
    use parry3d_f64::shape::{TriMesh, TriMeshFlags};
    let vertices = rest.iter().map(|&x| Vector::from_array(x)).collect();
    let Ok(mesh) = TriMesh::with_flags(vertices, triangles.to_vec(), TriMeshFlags::ORIENTED) else {
        // No triangles: nothing is inside.
        return vec![false; points.len()];
    };
    // The projection is `None` when no triangle is within a finite distance (a point or
    // mesh far past f64's range): such a point is not inside. (`contains_local_point`
    // would panic there; the parser property tests found it.)
    let inside = |p: [f64; 3]| {
        mesh.project_local_point_and_get_location_with_max_dist(
            Vector::from_array(p),
            true,
            f64::MAX,
        )
        .is_some_and(|(projection, _)| projection.is_inside)
    };
    points.iter().map(|&p| inside(p)).collect()
}
