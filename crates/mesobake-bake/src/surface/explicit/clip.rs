//! One prism's share of the export: the tile copies that overlap it clipped against its sides
//! and w = 0, 1 with canonical points and decisions, mapped through the prism and adaptively
//! subdivided (steps 2 to 5 of the algorithm in the parent module).

use super::tile::{PreparedTile, TileVertex, floor, point};
use super::*;

/// One side of a prism, oriented from the corner with the smaller welded id.
pub(super) struct Side {
    /// Start and end corners (prism corner indices) of the oriented side.
    pub(super) a: usize,
    pub(super) b: usize,
    /// Frame origin: the lattice point at the start corner's texture coordinate.
    pub(super) origin: [i64; 2],
    /// Start corner and direction in that frame.
    pub(super) ua: DVec2,
    pub(super) d: DVec2,
    /// +1 or −1: the prism lies where `sign · cross(d, x − ua) ≥ 0`.
    pub(super) sign: f64,
    /// Start corner and direction in the prism's frame (for approximate classification).
    pub(super) ua_p: DVec2,
    pub(super) d_p: DVec2,
    /// No other prism shares this side.
    pub(super) boundary: bool,
}

impl Side {
    /// cross(d, x − ua) for `x` in the side's frame: the canonical side value.
    pub(super) fn canonical(&self, x: DVec2) -> f64 {
        self.d.x * (x.y - self.ua.y) - self.d.y * (x.x - self.ua.x)
    }

    /// Prism coordinates of the point of the side's line nearest `x` (side frame) at `w`.
    pub(super) fn at(&self, x: DVec2, w: f64) -> PrismPoint {
        let r = x - self.ua;
        // Not clamped: a point beyond the side's ends lies outside a neighbouring plane, and
        // must stay there to be clipped away.
        let l = (r.x * self.d.x + r.y * self.d.y) / self.d.length_squared();
        let mut bary = [0.0; 3];
        bary[self.a] = 1.0 - l;
        bary[self.b] = l;
        PrismPoint { bary, w }
    }
}

/// A polygon vertex during clipping.
#[derive(Clone, Copy, Debug)]
pub(super) struct Vert {
    /// Final prism coordinates.
    pub(super) q: PrismPoint,
    /// Texture point in the prism's frame.
    pub(super) tex: DVec3,
    /// Values of the five planes' inside functions (≥ 0 inside).
    pub(super) f: [f64; 5],
    /// Bit i: the vertex lies exactly on plane i.
    pub(super) on: u8,
}

/// What a polygon edge lies on: a tile edge (corner indices) or a clipping plane.
#[derive(Clone, Copy, Debug)]
pub(super) enum Support {
    Edge(usize, usize),
    Plane(usize),
}

/// A subdivision node: prism coordinates and their exact image.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) q: PrismPoint,
    pub(super) p: DVec3,
}

/// One prism's share of the output (locally welded).
#[derive(Default)]
pub(super) struct PrismOutput {
    pub(super) positions: Vec<DVec3>,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) sources: Vec<TriangleSource>,
    pub(super) clipped: usize,
    pub(super) depth_limited: usize,
    pub(super) mirrored: bool,
    pub(super) max_deviation: f64,
}

/// Everything one prism's clipping and subdivision need.
pub(super) struct PrismContext<'a> {
    pub(super) prism: &'a Prism,
    pub(super) index: u32,
    pub(super) tile: &'a PreparedTile,
    pub(super) params: &'a ExplicitParams,
    /// Prism frame origin and the UV corners in it.
    pub(super) origin: [i64; 2],
    pub(super) corners: [DVec2; 3],
    /// Inverse of [c₁ − c₀, c₂ − c₀] (rows), for barycentric coordinates.
    pub(super) inverse: [[f64; 2]; 2],
    pub(super) sides: [Side; 3],
    /// Per side, its inside function at the opposite corner (> 0): the function is this times
    /// the opposite corner's barycentric coordinate.
    pub(super) heights: [f64; 3],
    /// Per corner: frame origin and the corner in it.
    pub(super) corner_origin: [[i64; 2]; 3],
    pub(super) corner_local: [DVec2; 3],
    /// The mapping reverses orientation: swap windings.
    pub(super) mirrored: bool,
}

impl<'a> PrismContext<'a> {
    pub(super) fn new(
        prism: &'a Prism,
        index: u32,
        boundary: [bool; 3],
        tile: &'a PreparedTile,
        params: &'a ExplicitParams,
    ) -> Self {
        let uv = prism.uv;
        let (lo, _) = uv_bounds(prism);
        let origin = floor(lo);
        let local = |u: DVec2, o: [i64; 2]| u - DVec2::new(o[0] as f64, o[1] as f64);
        let corners = uv.map(|u| local(u, origin));
        let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
        let det = e1.perp_dot(e2);
        let inverse = [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]];
        let uv_sign = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).signum();
        let sides = [0, 1, 2].map(|k| {
            let (i, j) = (k, (k + 1) % 3);
            let forward = (prism.welded[i], i) < (prism.welded[j], j);
            let (a, b) = if forward { (i, j) } else { (j, i) };
            let o = floor(uv[a]);
            let (ua, ub) = (local(uv[a], o), local(uv[b], o));
            Side {
                a,
                b,
                origin: o,
                ua,
                d: ub - ua,
                sign: if forward { uv_sign } else { -uv_sign },
                ua_p: corners[a],
                d_p: corners[b] - corners[a],
                boundary: boundary[k],
            }
        });
        let heights = [0, 1, 2].map(|k| {
            let s = &sides[k];
            let r = corners[(k + 2) % 3] - s.ua_p;
            s.sign * (s.d_p.x * r.y - s.d_p.y * r.x)
        });
        let corner_origin = uv.map(floor);
        let corner_local = [0, 1, 2].map(|c| local(uv[c], corner_origin[c]));
        let centre = PrismPoint {
            bary: [1.0 / 3.0; 3],
            w: 0.5,
        };
        let mirrored = prism
            .jacobian(centre)
            .is_some_and(|j| j.determinant() < 0.0);
        PrismContext {
            prism,
            index,
            tile,
            params,
            origin,
            corners,
            inverse,
            sides,
            heights,
            corner_origin,
            corner_local,
            mirrored,
        }
    }

    pub(super) fn point(&self, v: TileVertex, origin: [i64; 2]) -> DVec3 {
        point(&self.tile.reps, v, origin)
    }

    /// Barycentric coordinates of a texture point in the prism's frame.
    pub(super) fn bary(&self, tex: DVec3) -> [f64; 3] {
        let r = tex.truncate() - self.corners[0];
        let m = &self.inverse;
        let b1 = m[0][0] * r.x + m[0][1] * r.y;
        let b2 = m[1][0] * r.x + m[1][1] * r.y;
        [1.0 - b1 - b2, b1, b2]
    }

    /// Texture point (prism frame) of prism coordinates.
    pub(super) fn texture(&self, q: PrismPoint) -> DVec3 {
        let c = &self.corners;
        (c[0] * q.bary[0] + c[1] * q.bary[1] + c[2] * q.bary[2]).extend(q.w)
    }

    /// The five inside functions at a texture point (prism frame), approximately.
    pub(super) fn plane_values(&self, tex: DVec3) -> [f64; 5] {
        let mut f = [0.0; 5];
        for (k, s) in self.sides.iter().enumerate() {
            let r = tex.truncate() - s.ua_p;
            f[k] = s.sign * (s.d_p.x * r.y - s.d_p.y * r.x);
        }
        f[W0] = tex.z;
        f[W1] = 1.0 - tex.z;
        f
    }

    /// An original tile vertex, classified exactly in each side's frame.
    pub(super) fn tile_vertex(&self, v: TileVertex) -> Vert {
        let tex = self.point(v, self.origin);
        let mut f = [0.0; 5];
        for (k, s) in self.sides.iter().enumerate() {
            f[k] = s.sign * s.canonical(self.point(v, s.origin).truncate());
        }
        f[W0] = tex.z;
        f[W1] = 1.0 - tex.z;
        let on = (0..5).fold(0u8, |m, i| if f[i] == 0.0 { m | 1 << i } else { m });
        let q = match on & 7 {
            0 => PrismPoint {
                bary: self.bary(tex),
                w: tex.z,
            },
            s if s.count_ones() == 1 => {
                let side = &self.sides[s.trailing_zeros() as usize];
                side.at(self.point(v, side.origin).truncate(), tex.z)
            }
            s => corner_point(corner_of(s), tex.z),
        };
        Vert { q, tex, f, on }
    }

    /// The endpoints of tile edge (i, j) of `tri` in canonical order, in the frame at `origin`.
    pub(super) fn edge(
        &self,
        tri: &[TileVertex; 3],
        i: usize,
        j: usize,
        origin: [i64; 2],
    ) -> (DVec3, DVec3) {
        let (p, r) = ordered(tri, i, j);
        (self.point(p, origin), self.point(r, origin))
    }

    /// The point where the polygon edge `s` → `e` lying on `support` crosses `plane`, computed
    /// from what defines it (see the module documentation), with inside-function values that
    /// every prism sharing one of its planes computes alike: on a side or at a corner, side j's
    /// value is its height times the barycentric coordinate of its opposite corner; inside,
    /// the edge endpoints' canonical side values interpolated.
    pub(super) fn cut(
        &self,
        tri: &[TileVertex; 3],
        support: Support,
        plane: usize,
        s: &Vert,
        e: &Vert,
    ) -> Vert {
        let mut on = (s.on & e.on) | 1 << plane;
        if let Support::Plane(r) = support {
            on |= 1 << r;
        }
        let fixed_w = if on & 1 << W0 != 0 {
            Some(0.0)
        } else if on & 1 << W1 != 0 {
            Some(1.0)
        } else {
            None
        };
        // Fallback for degenerate configurations: interpolate between the polygon vertices.
        let t = s.f[plane] / (s.f[plane] - e.f[plane]);
        let fallback_tex = s.tex + (e.tex - s.tex) * t;
        // A cut on one side k, by a tile edge or by the tile plane's level line at w = 0 or 1:
        // on which side of each end corner of k the cutting line passes, evaluated in the
        // corner's frame as every prism around that corner does. Exactly through a corner:
        // the cut is that corner. Otherwise the signs decide, for all prisms alike, whether
        // the cut lies inside the other sides through that corner (a consistent symbolic
        // perturbation where round-off alone would not agree).
        let mut ends = None;
        if on & 7 == 1 << plane || (plane >= W0 && on & 7 != 0 && (on & 7).count_ones() == 1) {
            let k = (on & 7).trailing_zeros() as usize;
            let side = &self.sides[k];
            let predicates = match (support, fixed_w) {
                (Support::Edge(i, j), _) if plane == k => {
                    let (p, r) = self.edge(tri, i, j, side.origin);
                    let slope = (r - p).truncate().perp_dot(side.d);
                    let g = |c| self.edge_orientation(tri, i, j, c);
                    Some((g(side.a), g(side.b), slope))
                }
                (Support::Plane(_), Some(w)) => {
                    let h = |c| self.plane_height(tri, c, w);
                    let v = tri.map(|t| self.point(t, side.origin));
                    let n = (v[1] - v[0]).cross(v[2] - v[0]);
                    Some((h(side.a), h(side.b), n.x * side.d.x + n.y * side.d.y))
                }
                _ => None,
            };
            if let Some((ga, gb, slope)) = predicates {
                if ga == 0.0 {
                    on |= corner_sides(side.a);
                } else if gb == 0.0 {
                    on |= corner_sides(side.b);
                } else {
                    // Along k from a (μ = 0) to b (μ = 1) the predicate is ga + μ·slope: the cut
                    // is beyond a iff sign(ga) = −sign(slope), before b iff sign(gb) = sign(slope).
                    let beyond_a = ga.signum() * -slope.signum();
                    let before_b = gb.signum() * slope.signum();
                    ends = Some((k, beyond_a, before_b));
                }
            }
        }
        // A tile edge cut by w = 0 or 1 away from the sides: the side values of the cut are
        // the endpoints' canonical values interpolated (exactly 0: it is on that side).
        let mut interior = None;
        if let (Support::Edge(i, j), Some(c), 0) = (support, fixed_w, on & 7) {
            let (vp, vr) = ordered(tri, i, j);
            let (p, r) = (self.point(vp, self.origin), self.point(vr, self.origin));
            let t = (c - p.z) / (r.z - p.z);
            let mut f = [0.0; 3];
            for (k, side) in self.sides.iter().enumerate() {
                let fp = side.canonical(self.point(vp, side.origin).truncate());
                let fr = side.canonical(self.point(vr, side.origin).truncate());
                f[k] = side.sign * (fp + (fr - fp) * t);
                if f[k] == 0.0 {
                    on |= 1 << k;
                }
            }
            interior = Some(((p + (r - p) * t).truncate().extend(c), f));
        }
        let sides = on & 7;
        let (q, tex) = match sides.count_ones() {
            0 => {
                let tex = interior.map_or(fallback_tex, |i| i.0);
                let w = fixed_w.unwrap_or(tex.z);
                (
                    PrismPoint {
                        bary: self.bary(tex),
                        w,
                    },
                    tex,
                )
            }
            1 => {
                let k = sides.trailing_zeros() as usize;
                let side = &self.sides[k];
                let q = match support {
                    Support::Edge(i, j) => {
                        let (vp, vr) = ordered(tri, i, j);
                        let (p, r) = (self.point(vp, side.origin), self.point(vr, side.origin));
                        let t = match fixed_w {
                            Some(c) if plane >= W0 => (c - p.z) / (r.z - p.z),
                            _ => {
                                let (fp, fr) =
                                    (side.canonical(p.truncate()), side.canonical(r.truncate()));
                                fp / (fp - fr)
                            }
                        };
                        let x = p + (r - p) * t;
                        side.at(x.truncate(), fixed_w.unwrap_or(x.z))
                    }
                    Support::Plane(_) => match fixed_w {
                        Some(c) => self.side_level(tri, side, c),
                        None => None,
                    }
                    .unwrap_or_else(|| {
                        let o = side.origin;
                        let shift = DVec2::new(
                            (self.origin[0] - o[0]) as f64,
                            (self.origin[1] - o[1]) as f64,
                        );
                        side.at(fallback_tex.truncate() + shift, fallback_tex.z)
                    }),
                };
                let q = PrismPoint {
                    bary: q.bary,
                    w: fixed_w.unwrap_or(q.w),
                };
                (q, self.texture(q))
            }
            _ => {
                let c = corner_of(sides);
                let w = fixed_w.unwrap_or_else(|| {
                    // Through an edge of the tile that passes the corner exactly, from that
                    // edge (as the prisms cutting the edge itself compute it), else from the
                    // triangle's plane.
                    let edge = match support {
                        Support::Edge(i, j) => Some((i, j)),
                        Support::Plane(_) => [(0, 1), (1, 2), (2, 0)]
                            .into_iter()
                            .find(|&(i, j)| self.edge_orientation(tri, i, j, c) == 0.0),
                    };
                    let w = match edge {
                        Some((i, j)) => self.edge_at_corner(tri, i, j, c),
                        None => self.plane_at_corner(tri, c),
                    };
                    w.unwrap_or(fallback_tex.z)
                });
                let q = corner_point(c, w);
                (q, self.texture(q))
            }
        };
        let mut f = match (sides, interior) {
            (0, Some((_, f))) => [f[0], f[1], f[2], 0.0, 0.0],
            (0, None) => self.plane_values(tex),
            _ => {
                let mut f = [0.0; 5];
                for (j, h) in self.heights.iter().enumerate() {
                    let o = (j + 2) % 3;
                    f[j] = h * q.bary[o];
                    if let Some((k, beyond_a, before_b)) = ends {
                        // Side j ≠ k passes through one end of k; its value is proportional
                        // to the barycentric coordinate of the other end.
                        let side = &self.sides[k];
                        let sign = if o == side.b { beyond_a } else { before_b };
                        if j != k {
                            f[j] = sign * f[j].abs().max(f64::MIN_POSITIVE);
                        }
                    }
                }
                f
            }
        };
        f[W0] = q.w;
        f[W1] = 1.0 - q.w;
        for (i, v) in f.iter_mut().enumerate() {
            if on & (1 << i) != 0 {
                *v = 0.0;
            }
        }
        Vert { q, tex, f, on }
    }

    /// Where the tile triangle's plane meets `side` at height `w`, from the triangle's corners
    /// in the side's frame.
    pub(super) fn side_level(
        &self,
        tri: &[TileVertex; 3],
        side: &Side,
        w: f64,
    ) -> Option<PrismPoint> {
        let v = tri.map(|t| self.point(t, side.origin));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let denom = n.x * side.d.x + n.y * side.d.y;
        let num = n.x * (side.ua.x - v[0].x) + n.y * (side.ua.y - v[0].y) + n.z * (w - v[0].z);
        let l = -num / denom;
        l.is_finite().then(|| side.at(side.ua + side.d * l, w))
    }

    /// Orientation of corner `c` against the (s, t) line of tile edge (i, j), in the corner's
    /// frame: zero iff the line passes exactly through the corner.
    pub(super) fn edge_orientation(
        &self,
        tri: &[TileVertex; 3],
        i: usize,
        j: usize,
        c: usize,
    ) -> f64 {
        let (p, r) = self.edge(tri, i, j, self.corner_origin[c]);
        (r - p)
            .truncate()
            .perp_dot(self.corner_local[c] - p.truncate())
    }

    /// The tile triangle's plane function n·(x − v₀) at corner `c` and height `w`, in the
    /// corner's frame: zero iff the plane passes exactly through that point.
    pub(super) fn plane_height(&self, tri: &[TileVertex; 3], c: usize, w: f64) -> f64 {
        let v = tri.map(|t| self.point(t, self.corner_origin[c]));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        n.dot(self.corner_local[c].extend(w) - v[0])
    }

    /// Height where tile edge (i, j) passes the vertical line of corner `c`, from the edge's
    /// endpoints in the corner's frame.
    pub(super) fn edge_at_corner(
        &self,
        tri: &[TileVertex; 3],
        i: usize,
        j: usize,
        c: usize,
    ) -> Option<f64> {
        let (p, r) = self.edge(tri, i, j, self.corner_origin[c]);
        let d = (r - p).truncate();
        let t = (self.corner_local[c] - p.truncate()).dot(d) / d.length_squared();
        let w = p.z + (r.z - p.z) * t;
        w.is_finite().then_some(w)
    }

    /// Height of the tile triangle's plane on the vertical line of corner `c`.
    pub(super) fn plane_at_corner(&self, tri: &[TileVertex; 3], c: usize) -> Option<f64> {
        let v = tri.map(|t| self.point(t, self.corner_origin[c]));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let u = self.corner_local[c];
        let w = v[0].z - (n.x * (u.x - v[0].x) + n.y * (u.y - v[0].y)) / n.z;
        w.is_finite().then_some(w)
    }

    /// Clips one tile triangle copy into `poly` (left empty when nothing is inside).
    pub(super) fn clip(
        &self,
        tri: &[TileVertex; 3],
        verts: [Vert; 3],
        poly: &mut Vec<(Vert, Support)>,
    ) {
        poly.clear();
        poly.extend([
            (verts[0], Support::Edge(0, 1)),
            (verts[1], Support::Edge(1, 2)),
            (verts[2], Support::Edge(2, 0)),
        ]);
        let mut next = Vec::with_capacity(8);
        for plane in 0..5 {
            if poly.iter().all(|(v, _)| v.f[plane] >= 0.0) {
                continue;
            }
            if poly.iter().all(|(v, _)| v.f[plane] <= 0.0) {
                poly.clear();
                return;
            }
            next.clear();
            let n = poly.len();
            for i in 0..n {
                let (s, support) = poly[i];
                let e = poly[(i + 1) % n].0;
                let (fs, fe) = (s.f[plane], e.f[plane]);
                if fs >= 0.0 {
                    let out = if fs == 0.0 && fe < 0.0 {
                        Support::Plane(plane)
                    } else {
                        support
                    };
                    next.push((s, out));
                }
                if fs > 0.0 && fe < 0.0 {
                    next.push((self.cut(tri, support, plane, &s, &e), Support::Plane(plane)));
                } else if fs < 0.0 && fe > 0.0 {
                    next.push((self.cut(tri, support, plane, &s, &e), support));
                }
            }
            std::mem::swap(poly, &mut next);
        }
    }

    /// Whether a clipped polygon whose vertices all lie on the planes `common` is kept: only
    /// a tile face lying in one plane, and in a shared side only in the prism it faces out of.
    pub(super) fn keep_flat(&self, tri: &[TileVertex; 3], verts: &[Vert; 3], common: u8) -> bool {
        if common.count_ones() != 1 || verts.iter().any(|v| v.on & common == 0) {
            return false;
        }
        let k = common.trailing_zeros() as usize;
        if k >= W0 || self.sides[k].boundary {
            return true;
        }
        let side = &self.sides[k];
        let v = tri.map(|t| self.point(t, self.origin));
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        // Inward normal of the side: the gradient of its inside function.
        let inward = DVec2::new(-side.d_p.y, side.d_p.x) * side.sign;
        n.truncate().dot(inward) < 0.0
    }

    pub(super) fn run(&self) -> PrismOutput {
        let mut out = PrismOutput {
            mirrored: self.mirrored,
            ..Default::default()
        };
        let mut welded: HashMap<[u64; 3], u32> = HashMap::new();
        let (lo, hi) = uv_bounds(self.prism);
        let slack = 1e-9 * (1.0 + lo.abs().max(hi.abs()).max_element());
        let (t_lo, t_hi) = (self.tile.lo, self.tile.hi);
        let m0 = (lo - t_hi - slack).ceil();
        let m1 = (hi - t_lo + slack).floor();
        let mut candidates = Vec::new();
        let mut poly = Vec::with_capacity(8);
        let mut n = m0.y;
        while n <= m1.y {
            let mut m = m0.x;
            while m <= m1.x {
                let offset = DVec2::new(m, n);
                self.tile
                    .query(lo - offset - slack, hi - offset + slack, &mut candidates);
                let shift = [m as i64, n as i64];
                for &c in &candidates {
                    let tri = self.tile.corners[c as usize].map(|v| TileVertex {
                        id: v.id,
                        shift: [v.shift[0] + shift[0], v.shift[1] + shift[1]],
                    });
                    self.triangle(&tri, &mut poly, &mut welded, &mut out);
                }
                m += 1.0;
            }
            n += 1.0;
        }
        out
    }

    /// Clips, triangulates, subdivides and emits one tile triangle copy.
    pub(super) fn triangle(
        &self,
        tri: &[TileVertex; 3],
        poly: &mut Vec<(Vert, Support)>,
        welded: &mut HashMap<[u64; 3], u32>,
        out: &mut PrismOutput,
    ) {
        let verts = tri.map(|v| self.tile_vertex(v));
        if (0..5).any(|i| verts.iter().all(|v| v.f[i] < 0.0)) {
            return;
        }
        if verts.iter().any(|v| v.f.iter().any(|&f| f < 0.0)) {
            out.clipped += 1;
        }
        self.clip(tri, verts, poly);
        poly.dedup_by(|a, b| same_point(&a.0.q, &b.0.q));
        while poly.len() > 1 && same_point(&poly[0].0.q, &poly[poly.len() - 1].0.q) {
            poly.pop();
        }
        if poly.len() < 3 {
            return;
        }
        let common = poly.iter().fold(0x1f, |m, (v, _)| m & v.on);
        if common != 0 && !self.keep_flat(tri, &verts, common) {
            return;
        }
        let node = |v: &Vert| Node {
            q: v.q,
            p: self.prism.point(v.q),
        };
        let first = node(&poly[0].0);
        let mut previous = node(&poly[1].0);
        for (v, _) in &poly[2..] {
            let current = node(v);
            self.refine([first, previous, current], 0, welded, out);
            previous = current;
        }
    }

    /// The split decision for edge (a, b): its texture midpoint's node when it splits, and
    /// the deviation measured. Symmetric in a and b.
    pub(super) fn split(&self, a: &Node, b: &Node) -> (Option<Node>, f64) {
        let q = PrismPoint {
            bary: [0, 1, 2].map(|i| (a.q.bary[i] + b.q.bary[i]) * 0.5),
            w: (a.q.w + b.q.w) * 0.5,
        };
        let p = self.prism.point(q);
        let deviation = (p - (a.p + b.p) * 0.5).length();
        let extent = (0..3)
            .map(|i| (a.q.bary[i] - b.q.bary[i]).abs())
            .fold((a.q.w - b.q.w).abs(), f64::max);
        let splits = deviation > self.params.tolerance && extent > MIN_EXTENT;
        (splits.then_some(Node { q, p }), deviation)
    }

    pub(super) fn refine(
        &self,
        t: [Node; 3],
        depth: u32,
        welded: &mut HashMap<[u64; 3], u32>,
        out: &mut PrismOutput,
    ) {
        let decisions = [0, 1, 2].map(|e| self.split(&t[e], &t[(e + 1) % 3]));
        let count = decisions.iter().filter(|d| d.0.is_some()).count();
        if count == 0 || depth == MAX_DEPTH {
            if count > 0 {
                out.depth_limited += 1;
            }
            let deviation = decisions.iter().fold(0.0f64, |m, d| m.max(d.1));
            out.max_deviation = out.max_deviation.max(deviation);
            self.emit(t, welded, out);
            return;
        }
        let mids = decisions.map(|d| d.0);
        let next = depth + 1;
        let mut recurse = |t: [Node; 3]| self.refine(t, next, welded, out);
        match count {
            1 => {
                // Rotate so that edge 0 (a → b) splits.
                let e = mids.iter().position(Option::is_some).unwrap_or(0);
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let m = mids[e].unwrap_or(a);
                recurse([a, m, c]);
                recurse([m, b, c]);
            }
            2 => {
                // Rotate so that edge 2 (c → a) is the one kept.
                let keep = mids.iter().position(Option::is_none).unwrap_or(2);
                let e = (keep + 1) % 3;
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let (m1, m2) = (mids[e].unwrap_or(a), mids[(e + 1) % 3].unwrap_or(b));
                recurse([m1, b, m2]);
                if (m2.p - a.p).length_squared() <= (c.p - m1.p).length_squared() {
                    recurse([a, m1, m2]);
                    recurse([a, m2, c]);
                } else {
                    recurse([a, m1, c]);
                    recurse([m1, m2, c]);
                }
            }
            _ => {
                let [ab, bc, ca] = [0, 1, 2].map(|e| mids[e].unwrap_or(t[e]));
                recurse([t[0], ab, ca]);
                recurse([ab, t[1], bc]);
                recurse([ca, bc, t[2]]);
                recurse([ab, bc, ca]);
            }
        }
    }

    /// Appends a final triangle (windings swapped where the mapping mirrors).
    pub(super) fn emit(
        &self,
        t: [Node; 3],
        welded: &mut HashMap<[u64; 3], u32>,
        out: &mut PrismOutput,
    ) {
        let t = if self.mirrored { [t[0], t[2], t[1]] } else { t };
        let ids = t.map(|n| {
            let next = out.positions.len() as u32;
            *welded.entry(position_key(n.p)).or_insert_with(|| {
                out.positions.push(n.p);
                next
            })
        });
        out.triangles.push(ids);
        if self.params.record_texture {
            out.sources.push(TriangleSource {
                prism: self.index,
                texture: t.map(|n| self.prism.texture(n.q)),
            });
        }
    }
}

/// The endpoints of tile edge (i, j) of `tri` in canonical order.
pub(super) fn ordered(tri: &[TileVertex; 3], i: usize, j: usize) -> (TileVertex, TileVertex) {
    if tri[i] < tri[j] {
        (tri[i], tri[j])
    } else {
        (tri[j], tri[i])
    }
}

/// Whether two prism points are bit-identical.
pub(super) fn same_point(a: &PrismPoint, b: &PrismPoint) -> bool {
    a.w == b.w && a.bary == b.bary
}

/// The corner shared by the sides in the bit set `sides` (at least two bits).
pub(super) fn corner_of(sides: u8) -> usize {
    match sides & 7 {
        0b110 => 2,
        0b101 => 0,
        _ => 1,
    }
}

/// The bits of the two sides that meet at corner `c` (side k runs from corner k to k+1).
pub(super) fn corner_sides(c: usize) -> u8 {
    1 << c | 1 << ((c + 2) % 3)
}

/// Prism coordinates of corner `c` at height `w`.
pub(super) fn corner_point(c: usize, w: f64) -> PrismPoint {
    let mut bary = [0.0; 3];
    bary[c] = 1.0;
    PrismPoint { bary, w }
}
