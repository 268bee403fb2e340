//! [`Phantom`]: the labelled anatomy inside the torso, as analytic shapes in material
//! (rest) coordinates, and where a straight line crosses them.
//!
//! Material coordinates are `[x, y, d]`: x and y relative to the torso's centre (world
//! axes), d the depth below the torso's top surface at rest (down positive). The torso's
//! particles only slide along their rest normals (top particles vertically), so a world
//! point maps to material coordinates through the vertical displacement field alone
//! (see `image.rs`), and a straight beam in the world is a straight line here.
//!
//! Shapes are axis-aligned boxes, ellipsoids and finite cylinders, listed in paint
//! order: where shapes overlap, the later one wins (a vessel inside the liver, the
//! medulla inside the cortex). Lines are intersected analytically, so boundaries have
//! exact positions (echoes move continuously with the probe) and a 128-line image costs
//! a few microseconds of geometry.

use super::tissue::Tissue;

/// The torso size the anatomy was laid out for \[m\]; other sizes scale it per axis.
pub const REFERENCE_SIZE: [f64; 3] = [0.28, 0.35, 0.105];

/// An axis-aligned analytic shape (material coordinates, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Box between two corners.
    Box { min: [f64; 3], max: [f64; 3] },
    /// Ellipsoid with semi-axes along x, y, d.
    Ellipsoid { center: [f64; 3], radii: [f64; 3] },
    /// Cylinder along `axis` (0 = x, 1 = y), circular in the other two coordinates,
    /// from `from` to `to` along the axis.
    Cylinder {
        axis: usize,
        center: [f64; 3],
        radius: f64,
        from: f64,
        to: f64,
    },
}

/// A labelled shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Structure {
    /// Its name (docs, tests).
    pub name: &'static str,
    /// Its tissue.
    pub tissue: Tissue,
    /// Its shape.
    pub shape: Shape,
}

/// Parameter interval `[t0, t1]` where `a + t·b` lies inside the box, if any.
fn box_interval(min: [f64; 3], max: [f64; 3], a: [f64; 3], b: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if b[k].abs() < 1e-15 {
            if a[k] < min[k] || a[k] > max[k] {
                return None;
            }
        } else {
            let (u, v) = ((min[k] - a[k]) / b[k], (max[k] - a[k]) / b[k]);
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
    }
    (t0 < t1).then_some((t0, t1))
}

/// Roots of `q2·t² + 2·q1·t + q0 = 0` as an ordered interval (where the quadratic is
/// negative), if real.
fn quadratic_interval(q2: f64, q1: f64, q0: f64) -> Option<(f64, f64)> {
    if q2 <= 1e-30 {
        return (q0 < 0.0).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let disc = q1 * q1 - q2 * q0;
    if disc <= 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some(((-q1 - s) / q2, (-q1 + s) / q2))
}

impl Shape {
    /// Parameter interval where the line `a + t·b` is inside the shape.
    pub fn interval(&self, a: [f64; 3], b: [f64; 3]) -> Option<(f64, f64)> {
        match *self {
            Shape::Box { min, max } => box_interval(min, max, a, b),
            Shape::Ellipsoid { center, radii } => {
                let (mut q2, mut q1, mut q0) = (0.0, 0.0, -1.0);
                for k in 0..3 {
                    let (p, v) = ((a[k] - center[k]) / radii[k], b[k] / radii[k]);
                    q2 += v * v;
                    q1 += p * v;
                    q0 += p * p;
                }
                quadratic_interval(q2, q1, q0)
            }
            Shape::Cylinder {
                axis,
                center,
                radius,
                from,
                to,
            } => {
                let (mut q2, mut q1, mut q0) = (0.0, 0.0, -1.0);
                for k in (0..3).filter(|&k| k != axis) {
                    let (p, v) = ((a[k] - center[k]) / radius, b[k] / radius);
                    q2 += v * v;
                    q1 += p * v;
                    q0 += p * p;
                }
                let (c0, c1) = quadratic_interval(q2, q1, q0)?;
                let mut min = [f64::NEG_INFINITY; 3];
                let mut max = [f64::INFINITY; 3];
                min[axis] = from;
                max[axis] = to;
                let (s0, s1) = box_interval(min, max, a, b)?;
                let (t0, t1) = (c0.max(s0), c1.min(s1));
                (t0 < t1).then_some((t0, t1))
            }
        }
    }

    /// Outward unit normal of the shape's surface nearest to `p` (material coordinates).
    pub fn normal(&self, p: [f64; 3]) -> [f64; 3] {
        let unit = |v: [f64; 3]| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n > 0.0 {
                [v[0] / n, v[1] / n, v[2] / n]
            } else {
                [0.0, 0.0, 1.0]
            }
        };
        match *self {
            Shape::Box { min, max } => {
                // The face nearest to p.
                let mut best = (f64::INFINITY, [0.0, 0.0, 1.0]);
                for k in 0..3 {
                    for (plane, sign) in [(min[k], -1.0), (max[k], 1.0)] {
                        let dist = (p[k] - plane).abs();
                        if dist < best.0 {
                            let mut n = [0.0; 3];
                            n[k] = sign;
                            best = (dist, n);
                        }
                    }
                }
                best.1
            }
            Shape::Ellipsoid { center, radii } => unit(std::array::from_fn(|k| {
                (p[k] - center[k]) / (radii[k] * radii[k])
            })),
            Shape::Cylinder {
                axis,
                center,
                radius,
                from,
                to,
            } => {
                let radial: [f64; 3] =
                    std::array::from_fn(|k| if k == axis { 0.0 } else { p[k] - center[k] });
                let r = radial.iter().map(|v| v * v).sum::<f64>().sqrt();
                let end = (p[axis] - from).abs().min((p[axis] - to).abs());
                if end < (r - radius).abs() {
                    let mut n = [0.0; 3];
                    n[axis] = if (p[axis] - from).abs() < (p[axis] - to).abs() {
                        -1.0
                    } else {
                        1.0
                    };
                    n
                } else {
                    unit(radial)
                }
            }
        }
    }
}

/// One stretch of a line through a single tissue.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Line parameter where it starts.
    pub t0: f64,
    /// Line parameter where it ends.
    pub t1: f64,
    /// Index of the structure (into [`Phantom::structures`]); `None` for the medium
    /// outside every structure.
    pub structure: Option<usize>,
    /// Its tissue.
    pub tissue: Tissue,
}

/// The labelled anatomy: structures in paint order over a background medium.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    /// Structures, later ones painted over earlier ones.
    pub structures: Vec<Structure>,
    /// What fills space outside every structure (air around the torso).
    pub background: Tissue,
}

/// Scratch buffers of [`Phantom::segments`], reused across lines.
#[derive(Debug, Default, Clone)]
pub struct SegmentScratch {
    hits: Vec<(usize, f64, f64)>,
    cuts: Vec<f64>,
}

impl Phantom {
    /// The abdomen phantom for a torso box of `size` (x across, y head (+) to feet, d
    /// depth) \[m\]: skin, subcutaneous fat, abdominal wall muscle, ribs over the upper
    /// (+y) third, liver (right, under the ribs) with two vessels, a kidney (lower left)
    /// with cortex, medulla and sinus, aorta and vena cava along y, and a vertebral body
    /// deep on the midline, over the table.
    pub fn abdomen(size: [f64; 3]) -> Self {
        let s: [f64; 3] = std::array::from_fn(|k| size[k] / REFERENCE_SIZE[k]);
        let p = |v: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| v[k] * s[k]) };
        let (hx, hy, h) = (size[0] / 2.0, size[1] / 2.0, size[2]);
        let layer = |name, tissue, d0: f64, d1: f64| Structure {
            name,
            tissue,
            shape: Shape::Box {
                min: [-hx, -hy, d0 * s[2]],
                max: [hx, hy, d1 * s[2]],
            },
        };
        let ellipsoid = |name, tissue, c: [f64; 3], r: [f64; 3]| Structure {
            name,
            tissue,
            shape: Shape::Ellipsoid {
                center: p(c),
                radii: p(r),
            },
        };
        let cylinder =
            |name, tissue, axis: usize, c: [f64; 3], radius: f64, from: f64, to: f64| Structure {
                name,
                tissue,
                shape: Shape::Cylinder {
                    axis,
                    center: p(c),
                    radius: radius * s[0].min(s[2]),
                    from: from * s[axis],
                    to: to * s[axis],
                },
            };
        // A vessel: a 1.2 mm echogenic wall around blood.
        let vessel = |list: &mut Vec<Structure>,
                      name: &'static str,
                      axis: usize,
                      c: [f64; 3],
                      radius: f64,
                      from: f64,
                      to: f64| {
            list.push(cylinder(
                "vessel_wall",
                Tissue::Connective,
                axis,
                c,
                radius + 0.0012,
                from,
                to,
            ));
            list.push(cylinder(name, Tissue::Blood, axis, c, radius, from, to));
        };
        let mut structures = vec![
            // Coupling gel above the skin (only reached where the face is coupled).
            Structure {
                name: "gel",
                tissue: Tissue::Gel,
                shape: Shape::Box {
                    min: [-hx, -hy, -0.01],
                    max: [hx, hy, 0.0],
                },
            },
            layer("cavity", Tissue::SoftTissue, 0.0, REFERENCE_SIZE[2]),
            layer("skin", Tissue::Skin, 0.0, 0.002),
            layer("subcutaneous_fat", Tissue::Fat, 0.002, 0.013),
            layer("abdominal_wall", Tissue::Muscle, 0.013, 0.025),
        ];
        // Ribs: across the body (along x) over the upper third, in the wall's depth.
        for (k, y) in [0.07, 0.097, 0.124, 0.151].into_iter().enumerate() {
            let name = ["rib_1", "rib_2", "rib_3", "rib_4"][k];
            structures.push(cylinder(
                name,
                Tissue::Bone,
                0,
                [0.0, y, 0.024],
                0.0055,
                -0.125,
                0.125,
            ));
        }
        // Liver (right, under the ribs) in its capsule, with two veins.
        structures.extend([
            ellipsoid(
                "liver_capsule",
                Tissue::Connective,
                [0.045, 0.075, 0.058],
                [0.0862, 0.0812, 0.0312],
            ),
            ellipsoid(
                "liver",
                Tissue::Liver,
                [0.045, 0.075, 0.058],
                [0.085, 0.08, 0.03],
            ),
        ]);
        vessel(
            &mut structures,
            "hepatic_vein",
            1,
            [0.035, 0.0, 0.052],
            0.004,
            0.02,
            0.14,
        );
        vessel(
            &mut structures,
            "portal_vein",
            0,
            [0.0, 0.06, 0.066],
            0.0035,
            0.0,
            0.1,
        );
        // Kidney (lower left): perirenal fat, capsule, cortex, six medullary pyramids
        // around the sinus.
        let kidney = [-0.07, -0.07, 0.062];
        let around = |name, tissue, grow: f64| {
            ellipsoid(
                name,
                tissue,
                kidney,
                [0.028 + grow, 0.052 + grow, 0.022 + grow],
            )
        };
        structures.extend([
            around("perirenal_fat", Tissue::VisceralFat, 0.005),
            around("kidney_capsule", Tissue::Connective, 0.001),
            around("kidney", Tissue::KidneyCortex, 0.0),
        ]);
        for (k, (dx, dy)) in [
            (-1.0, -1.0),
            (-1.0, 0.0),
            (-1.0, 1.0),
            (1.0, -1.0),
            (1.0, 0.0),
            (1.0, 1.0),
        ]
        .into_iter()
        .enumerate()
        {
            structures.push(ellipsoid(
                [
                    "pyramid_1",
                    "pyramid_2",
                    "pyramid_3",
                    "pyramid_4",
                    "pyramid_5",
                    "pyramid_6",
                ][k],
                Tissue::KidneyMedulla,
                [kidney[0] + 0.011 * dx, kidney[1] + 0.026 * dy, kidney[2]],
                [0.006, 0.011, 0.009],
            ));
        }
        structures.push(ellipsoid(
            "renal_sinus",
            Tissue::VisceralFat,
            [kidney[0] + 0.002, kidney[1], kidney[2]],
            [0.007, 0.03, 0.007],
        ));
        // Great vessels along the body, and a vertebral body on the midline.
        vessel(
            &mut structures,
            "aorta",
            1,
            [-0.012, 0.0, 0.076],
            0.009,
            -0.175,
            0.175,
        );
        vessel(
            &mut structures,
            "vena_cava",
            1,
            [0.022, 0.0, 0.074],
            0.0105,
            -0.175,
            0.175,
        );
        structures.push(cylinder(
            "vertebra",
            Tissue::Bone,
            1,
            [0.0, 0.0, 0.103],
            0.016,
            -0.175,
            0.175,
        ));
        // The table under the torso (wider than it), painted last: nothing reaches below.
        structures.push(Structure {
            name: "table",
            tissue: Tissue::Table,
            shape: Shape::Box {
                min: [-1.0, -1.0, h],
                max: [1.0, 1.0, h + 0.05],
            },
        });
        Self {
            structures,
            background: Tissue::Air,
        }
    }

    /// The tissue at material point `p`.
    pub fn tissue_at(&self, p: [f64; 3]) -> Tissue {
        let inside = |s: &Structure| {
            s.shape
                .interval(p, [0.0, 0.0, 1.0])
                .is_some_and(|(t0, t1)| t0 <= 0.0 && t1 >= 0.0)
        };
        self.structures
            .iter()
            .rev()
            .find(|s| inside(s))
            .map_or(self.background, |s| s.tissue)
    }

    /// The stretches of tissue along `a + t·b` for `t ∈ [0, t_max]`, in order, adjacent
    /// stretches of the same tissue merged (no echo between them).
    pub fn segments(
        &self,
        a: [f64; 3],
        b: [f64; 3],
        t_max: f64,
        scratch: &mut SegmentScratch,
        out: &mut Vec<Segment>,
    ) {
        out.clear();
        scratch.hits.clear();
        scratch.cuts.clear();
        scratch.cuts.extend([0.0, t_max]);
        for (i, s) in self.structures.iter().enumerate() {
            if let Some((t0, t1)) = s.shape.interval(a, b) {
                let (t0, t1) = (t0.max(0.0), t1.min(t_max));
                if t0 < t1 {
                    scratch.hits.push((i, t0, t1));
                    scratch.cuts.extend([t0, t1]);
                }
            }
        }
        scratch.cuts.sort_by(f64::total_cmp);
        scratch.cuts.dedup();
        for w in scratch.cuts.windows(2) {
            let (t0, t1) = (w[0], w[1]);
            if t1 - t0 < 1e-12 {
                continue;
            }
            let mid = 0.5 * (t0 + t1);
            let structure = scratch
                .hits
                .iter()
                .rev()
                .find(|&&(_, h0, h1)| h0 <= mid && mid <= h1)
                .map(|&(i, _, _)| i);
            let tissue = structure.map_or(self.background, |i| self.structures[i].tissue);
            match out.last_mut() {
                Some(last) if last.tissue == tissue => last.t1 = t1,
                _ => out.push(Segment {
                    t0,
                    t1,
                    structure,
                    tissue,
                }),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_line_crosses_the_layers_in_order() {
        let phantom = Phantom::abdomen(REFERENCE_SIZE);
        let mut out = Vec::new();
        // Centre of the torso, from 5 mm above the skin straight down 12 cm.
        phantom.segments(
            [0.0, 0.0, -0.005],
            [0.0, 0.0, 1.0],
            0.12,
            &mut SegmentScratch::default(),
            &mut out,
        );
        let tissues: Vec<Tissue> = out.iter().map(|s| s.tissue).collect();
        assert_eq!(
            &tissues[..5],
            &[
                Tissue::Gel,
                Tissue::Skin,
                Tissue::Fat,
                Tissue::Muscle,
                Tissue::SoftTissue
            ]
        );
        // The vertebra's top, then the table.
        assert!(tissues.contains(&Tissue::Bone));
        assert_eq!(*tissues.last().unwrap(), Tissue::Table);
        let skin = out[1];
        assert!((skin.t0 - 0.005).abs() < 1e-12 && (skin.t1 - 0.007).abs() < 1e-12);
        // Segments tile the line.
        for w in out.windows(2) {
            assert_eq!(w[0].t1, w[1].t0);
        }
    }

    #[test]
    fn point_queries_agree_with_segments() {
        let phantom = Phantom::abdomen([0.29, 0.34, 0.1]);
        let (a, b) = ([-0.07, -0.09, 0.0], [0.01, 0.3, 1.0]);
        let mut out = Vec::new();
        phantom.segments(a, b, 0.1, &mut SegmentScratch::default(), &mut out);
        assert!(out.iter().any(|s| s.tissue == Tissue::KidneyCortex));
        for s in &out {
            let t = 0.5 * (s.t0 + s.t1);
            let p: [f64; 3] = std::array::from_fn(|k| a[k] + t * b[k]);
            assert_eq!(phantom.tissue_at(p), s.tissue, "at t = {t}");
        }
    }

    #[test]
    fn normals_point_outward() {
        let e = Shape::Ellipsoid {
            center: [0.0, 0.0, 0.05],
            radii: [0.02, 0.03, 0.01],
        };
        assert_eq!(e.normal([0.0, 0.0, 0.04]), [0.0, 0.0, -1.0]);
        let c = Shape::Cylinder {
            axis: 0,
            center: [0.0, 0.1, 0.02],
            radius: 0.005,
            from: -0.1,
            to: 0.1,
        };
        let n = c.normal([0.0, 0.1, 0.015]);
        assert!((n[2] + 1.0).abs() < 1e-12);
    }
}
