//! The camera, rasterizer and shading of [`Scene::render`].
//!
//! The camera is orthographic: a point p goes to screen coordinates (p·right, p·up) and depth
//! p·forward, `forward` looking along the view's azimuth and down by its elevation. The scale
//! and centre are fitted to the projected vertices (and the ground plate) with the view's
//! margin. Samples are drawn in horizontal bands in parallel; within a band, triangle after
//! triangle in scene order, each sample's edge functions and depth evaluated from the
//! triangle's projected corners alone (no incremental stepping), so a sample's value does not
//! depend on the banding. A sample takes a triangle's colour when the triangle covers its
//! centre and is strictly nearer than what it holds. Each triangle is one colour: its own,
//! lit by the fixed sun, a sky term and ambient light on the side facing the camera (faces of
//! either winding are lit alike). An outline pass then darkens samples whose neighbour is much
//! farther (a silhouette), and the samples are averaged down to pixels over a sky gradient.

use glam::Vec3;
use rayon::prelude::*;

use super::{Image, Scene, View, MAX_SAMPLES, MAX_SIDE};
use crate::color::srgb_u8_to_linear;

/// Where the sunlight comes from, relative to the camera: its bearing is the view's plus
/// `SUN_TURN` degrees (240: behind the camera, on its left), and its height above the horizon.
/// So whatever the view, roofs are the brightest, the walls facing the camera's left lit, those
/// facing its right less, those facing away from the sun in the shade.
const SUN_TURN: f32 = 240.0;
const SUN_ELEVATION: f32 = 50.0;

/// Light on a face: `AMBIENT` everywhere, `SKY` times how much it faces up (0 facing down, 1
/// facing up), `SUN` times the cosine to the sun.
const AMBIENT: f32 = 0.20;
const SKY: f32 = 0.20;
const SUN: f32 = 0.75;

/// How much an outline darkens a sample.
const OUTLINE: f32 = 0.55;

/// The ground plate's colour (sRGB) and its border around the scene's plan, as a fraction of
/// the plan's larger side.
const GROUND: [u8; 3] = [200, 202, 190];
const GROUND_BORDER: f32 = 0.04;

/// The sky at the picture's top and bottom (sRGB).
const SKY_TOP: [u8; 3] = [150, 186, 222];
const SKY_BOTTOM: [u8; 3] = [228, 236, 243];

/// Sample rows a rendering task draws.
const BAND: usize = 32;

/// The axis-aligned bounds of the scene's vertices.
pub(super) fn bounds(scene: &Scene) -> Option<([f32; 3], [f32; 3])> {
    scene
        .positions
        .par_chunks(1 << 16)
        .map(|c| {
            c.iter().fold(
                ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
                |(lo, hi), p| {
                    (
                        [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                        [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
                    )
                },
            )
        })
        .reduce_with(|a, b| {
            (
                [a.0[0].min(b.0[0]), a.0[1].min(b.0[1]), a.0[2].min(b.0[2])],
                [a.1[0].max(b.1[0]), a.1[1].max(b.1[1]), a.1[2].max(b.1[2])],
            )
        })
        .filter(|(lo, hi)| lo[0] <= hi[0])
}

/// The view's sizes and angles made safe: sides 1..=MAX_SIDE, supersampling 1..=4 and lowered
/// until the samples fit MAX_SAMPLES, elevation 5..=90, margin 0..=0.45.
struct Frame {
    width: usize,
    height: usize,
    ss: usize,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    margin: f32,
}

impl Frame {
    fn new(view: &View, scene: &Scene) -> Frame {
        let width = view.width.clamp(1, MAX_SIDE) as usize;
        let height = view.height.clamp(1, MAX_SIDE) as usize;
        let mut ss = view.supersample.clamp(1, 4) as usize;
        while ss > 1 && (width * height * ss * ss) as u64 > MAX_SAMPLES {
            ss -= 1;
        }
        let azimuth = view
            .azimuth
            .filter(|a| a.is_finite())
            .unwrap_or_else(|| auto_azimuth(scene))
            .to_radians();
        let elevation = if view.elevation.is_finite() {
            view.elevation.clamp(5.0, 90.0).to_radians()
        } else {
            View::default().elevation.to_radians()
        };
        let (sa, ca) = azimuth.sin_cos();
        let (se, ce) = elevation.sin_cos();
        let forward = Vec3::new((sa * ce) as f32, (ca * ce) as f32, -se as f32);
        let right = Vec3::new(ca as f32, -sa as f32, 0.0);
        let up = right.cross(forward);
        let margin = if view.margin.is_finite() {
            view.margin.clamp(0.0, 0.45) as f32
        } else {
            0.0
        };
        Frame {
            width,
            height,
            ss,
            right,
            up,
            forward,
            margin,
        }
    }
}

/// The mapping of a frame point to sample coordinates (x right, y down) and depth.
#[derive(Clone, Copy)]
struct Projection {
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    /// Screen coordinates (p·right, p·up) of the picture's centre.
    centre: [f32; 2],
    /// Samples per metre.
    scale: f32,
    /// Half the sample buffer's sides.
    half: [f32; 2],
}

impl Projection {
    fn apply(&self, p: Vec3) -> [f32; 3] {
        [
            (p.dot(self.right) - self.centre[0]) * self.scale + self.half[0],
            self.half[1] - (p.dot(self.up) - self.centre[1]) * self.scale,
            p.dot(self.forward),
        ]
    }
}

/// A triangle ready to draw: corners in samples and depth, and its colour.
#[derive(Clone, Copy)]
struct Screen {
    corners: [[f32; 3]; 3],
    color: [u8; 3],
}

pub(super) fn render(scene: &Scene, view: &View) -> Image {
    let frame = Frame::new(view, scene);
    let (sw, sh) = (frame.width * frame.ss, frame.height * frame.ss);
    let mut depth = vec![f32::INFINITY; sw * sh];
    let mut color = vec![[0u8; 3]; sw * sh];

    if let Some((projection, reach)) = fit(scene, &frame) {
        let light = Light::new(&frame);
        let ground = scene
            .bounds()
            .filter(|_| view.ground)
            .map(|(lo, _)| ground_plate(&frame, &projection, reach, lo[2]));
        let ground_tris: Vec<Screen> = ground
            .iter()
            .flat_map(|g| {
                [[g[0], g[1], g[2]], [g[0], g[2], g[3]]]
                    .map(|t| screen(&projection, &light, t.map(Vec3::from), GROUND))
            })
            .flatten()
            .collect();
        // Each run's rows in samples, to skip the runs a band does not meet.
        let run_rows: Vec<[f32; 2]> = scene
            .runs
            .par_iter()
            .map(|r| {
                let end = scene.triangles[r.first_triangle..r.end_triangle]
                    .iter()
                    .flatten()
                    .map(|&i| usize::from(i))
                    .max()
                    .map_or(r.first_vertex, |m| r.first_vertex + m + 1);
                scene.positions[r.first_vertex..end]
                    .iter()
                    .map(|p| projection.apply(Vec3::from(*p))[1])
                    .fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], y| {
                        [lo.min(y), hi.max(y)]
                    })
            })
            .collect();
        depth
            .par_chunks_mut(BAND * sw)
            .zip(color.par_chunks_mut(BAND * sw))
            .enumerate()
            .for_each(|(band, (depth, color))| {
                let mut target = Band {
                    width: sw,
                    top: band * BAND,
                    rows: depth.len() / sw,
                    depth,
                    color,
                };
                for t in &ground_tris {
                    target.draw(t);
                }
                let (top, bottom) = (target.top as f32, (target.top + target.rows) as f32);
                for (r, rows) in scene.runs.iter().zip(&run_rows) {
                    if rows[1] < top || rows[0] > bottom {
                        continue;
                    }
                    let at = |i: u16| Vec3::from(scene.positions[r.first_vertex + usize::from(i)]);
                    for t in &scene.triangles[r.first_triangle..r.end_triangle] {
                        let corners = [at(t[0]), at(t[1]), at(t[2])];
                        if let Some(s) = screen(&projection, &light, corners, r.color) {
                            target.draw(&s);
                        }
                    }
                }
            });
        outline(&depth, &mut color, sw, projection.scale);
    }
    resolve(&frame, &depth, &color)
}

/// The ground plate's corners (counter-clockwise from above), at height `z` (a little below
/// the scene's lowest point, so walls' feet do not fight it): a rectangle square to the view
/// that runs past the picture's sides and bottom, its far edge [`GROUND_BORDER`] of the scene's
/// plan beyond the farthest point (`reach`), so that it ends in a horizon with the sky above.
fn ground_plate(frame: &Frame, p: &Projection, reach: Reach, z: f32) -> [[f32; 3]; 4] {
    let ahead = Vec3::new(frame.forward.x, frame.forward.y, 0.0).normalize_or_zero();
    let plan = (reach.right[1] - reach.right[0]).max(reach.ahead[1] - reach.ahead[0]);
    // Far enough to cover the picture whatever the angle.
    let beyond = 2.0 * (p.half[0] + p.half[1]) / p.scale.max(1e-6) + plan;
    let far = reach.ahead[1] + GROUND_BORDER * plan.max(1.0);
    let near = reach.ahead[0] - beyond;
    let (left, right) = (reach.right[0] - beyond, reach.right[1] + beyond);
    let at = |r: f32, a: f32| {
        let q = frame.right * r + ahead * a;
        [q.x, q.y, z - 0.05]
    };
    [
        at(left, near),
        at(right, near),
        at(right, far),
        at(left, far),
    ]
}

/// How far the scene's vertices reach along the view's horizontal axes: `right` and `ahead`
/// (forward in plan), each (min, max).
#[derive(Clone, Copy)]
struct Reach {
    right: [f32; 2],
    ahead: [f32; 2],
}

/// The projection that fits the scene into the frame with its margin, and how far the scene
/// reaches in plan; `None` for an empty scene.
fn fit(scene: &Scene, frame: &Frame) -> Option<(Projection, Reach)> {
    let (right, up) = (frame.right, frame.up);
    let ahead = Vec3::new(frame.forward.x, frame.forward.y, 0.0).normalize_or_zero();
    // (min, max) of p·right, p·up and p·ahead.
    let extent = |ps: &[[f32; 3]]| {
        ps.iter()
            .fold([f32::INFINITY, f32::NEG_INFINITY].repeat(3), |mut e, p| {
                let p = Vec3::from(*p);
                for (k, axis) in [right, up, ahead].iter().enumerate() {
                    let v = p.dot(*axis);
                    e[2 * k] = e[2 * k].min(v);
                    e[2 * k + 1] = e[2 * k + 1].max(v);
                }
                e
            })
    };
    let e = scene
        .positions
        .par_chunks(1 << 16)
        .map(extent)
        .reduce_with(|a, b| {
            (0..6)
                .map(|k| {
                    if k % 2 == 0 {
                        a[k].min(b[k])
                    } else {
                        a[k].max(b[k])
                    }
                })
                .collect()
        })?;
    if !e.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (sw, sh) = (
        (frame.width * frame.ss) as f32,
        (frame.height * frame.ss) as f32,
    );
    let border = frame.margin * sw.min(sh);
    let (span_x, span_y) = ((e[1] - e[0]).max(1e-3), (e[3] - e[2]).max(1e-3));
    let scale = ((sw - 2.0 * border).max(1.0) / span_x).min((sh - 2.0 * border).max(1.0) / span_y);
    let projection = Projection {
        right,
        up,
        forward: frame.forward,
        centre: [(e[0] + e[1]) / 2.0, (e[2] + e[3]) / 2.0],
        scale,
        half: [sw / 2.0, sh / 2.0],
    };
    let reach = Reach {
        right: [e[0], e[1]],
        ahead: [e[4], e[5]],
    };
    Some((projection, reach))
}

/// The bearing (degrees clockwise from north) to look towards so that the scene's plan lies
/// across the picture: square to the principal axis of its vertices, from its southern side
/// (the camera never looks south). A plan with no clear axis (the two spreads within 20 % of
/// each other) is seen from the south-south-west (22.5).
fn auto_azimuth(scene: &Scene) -> f64 {
    const DEFAULT: f64 = 22.5;
    let Some((lo, hi)) = scene.bounds() else {
        return DEFAULT;
    };
    let (cx, cy) = (
        (f64::from(lo[0]) + f64::from(hi[0])) / 2.0,
        (f64::from(lo[1]) + f64::from(hi[1])) / 2.0,
    );
    // Second moments about the bounds' centre, summed in fixed chunks then in order, so the
    // sum does not depend on the thread count.
    let parts: Vec<[f64; 6]> = scene
        .positions
        .par_chunks(1 << 16)
        .map(|c| {
            c.iter().fold([0.0; 6], |mut m, p| {
                let (x, y) = (f64::from(p[0]) - cx, f64::from(p[1]) - cy);
                m[0] += 1.0;
                m[1] += x;
                m[2] += y;
                m[3] += x * x;
                m[4] += y * y;
                m[5] += x * y;
                m
            })
        })
        .collect();
    let m = parts.iter().fold([0.0; 6], |mut a, b| {
        (0..6).for_each(|k| a[k] += b[k]);
        a
    });
    if m[0] < 2.0 {
        return DEFAULT;
    }
    let (mx, my) = (m[1] / m[0], m[2] / m[0]);
    let sxx = m[3] / m[0] - mx * mx;
    let syy = m[4] / m[0] - my * my;
    let sxy = m[5] / m[0] - mx * my;
    // Eigenvalues of the covariance: the spreads along and across the principal axis.
    let mean = (sxx + syy) / 2.0;
    let d = (((sxx - syy) / 2.0).powi(2) + sxy * sxy).sqrt();
    let (major, minor) = (mean + d, mean - d);
    if !(major.is_finite() && minor.is_finite()) || major <= 1.2 * minor.max(0.0) {
        return DEFAULT;
    }
    // The principal axis, as an angle from east; the picture's right runs along it.
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    // right = (cos a, -sin a) = (cos θ, sin θ) gives a = -θ; looking north-ish needs cos θ ≥ 0.
    let a = if theta.cos() >= 0.0 {
        -theta
    } else {
        std::f64::consts::PI - theta
    };
    a.to_degrees().rem_euclid(360.0)
}

/// The light of a frame: the sun's direction (towards the sun) and the camera's forward.
struct Light {
    sun: Vec3,
    forward: Vec3,
}

impl Light {
    fn new(frame: &Frame) -> Light {
        let bearing = frame.forward.x.atan2(frame.forward.y).to_degrees() + SUN_TURN;
        let (sa, ca) = bearing.to_radians().sin_cos();
        let (se, ce) = SUN_ELEVATION.to_radians().sin_cos();
        Light {
            sun: Vec3::new(sa * ce, ca * ce, se),
            forward: frame.forward,
        }
    }

    /// `base` (sRGB) lit on a face of unit normal `n`.
    fn shade(&self, base: [u8; 3], n: Vec3) -> [u8; 3] {
        // The side facing the camera is the one seen.
        let n = if n.dot(self.forward) > 0.0 { -n } else { n };
        let light = AMBIENT + SKY * (0.5 + 0.5 * n.z) + SUN * n.dot(self.sun).max(0.0);
        base.map(|c| linear_to_srgb(linear_of(c) * light))
    }
}

/// A triangle projected and lit; `None` when it is degenerate or not finite.
fn screen(p: &Projection, light: &Light, corners: [Vec3; 3], base: [u8; 3]) -> Option<Screen> {
    let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    let len = n.length();
    if !(len.is_finite() && len > 0.0) {
        return None;
    }
    Some(Screen {
        corners: corners.map(|c| p.apply(c)),
        color: light.shade(base, n / len),
    })
}

/// One band of the sample buffers.
struct Band<'a> {
    width: usize,
    /// The band's first row in the whole buffer.
    top: usize,
    rows: usize,
    depth: &'a mut [f32],
    color: &'a mut [[u8; 3]],
}

impl Band<'_> {
    /// Draws `t` on the samples of the band whose centre it covers, where it is nearer.
    fn draw(&mut self, t: &Screen) {
        let [a, b, c] = t.corners;
        let area = edge(a, b, c);
        if !(area.is_finite() && area != 0.0) {
            return;
        }
        let min_x = a[0].min(b[0]).min(c[0]);
        let max_x = a[0].max(b[0]).max(c[0]);
        let min_y = a[1].min(b[1]).min(c[1]);
        let max_y = a[1].max(b[1]).max(c[1]);
        let top = self.top as f32;
        let bottom = (self.top + self.rows) as f32;
        if max_x < 0.0 || min_x > self.width as f32 || max_y < top || min_y > bottom {
            return;
        }
        // Samples whose centre (x + 0.5) may lie in the triangle.
        let x0 = (min_x - 0.5).ceil().max(0.0) as usize;
        let x1 = ((max_x - 0.5).floor().min(self.width as f32 - 1.0)).max(-1.0);
        let y0 = (min_y - 0.5).ceil().max(top) as usize;
        let y1 = (max_y - 0.5).floor().min(bottom - 1.0);
        if x1 < 0.0 || y1 < y0 as f32 {
            return;
        }
        let (x1, y1) = (x1 as usize, y1 as usize);
        let inv = 1.0 / area;
        for y in y0..=y1 {
            let row = (y - self.top) * self.width;
            for x in x0..=x1 {
                let p = [x as f32 + 0.5, y as f32 + 0.5, 0.0];
                let w0 = edge(b, c, p) * inv;
                let w1 = edge(c, a, p) * inv;
                let w2 = edge(a, b, p) * inv;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a[2] + w1 * b[2] + w2 * c[2];
                let i = row + x;
                if z < self.depth[i] {
                    self.depth[i] = z;
                    self.color[i] = t.color;
                }
            }
        }
    }
}

/// Twice the signed area of (a, b, p) in the screen plane.
fn edge(a: [f32; 3], b: [f32; 3], p: [f32; 3]) -> f32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Darkens the samples on the near side of a depth jump (a silhouette against what is behind,
/// or against the sky): a neighbour farther by more than a metre plus what the steepest face
/// slopes over three samples.
fn outline(depth: &[f32], color: &mut [[u8; 3]], width: usize, scale: f32) {
    let jump = 1.0 + 6.0 / scale.max(1e-6);
    let height = depth.len() / width;
    color
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, c) in row.iter_mut().enumerate() {
                let d = depth[y * width + x];
                if !d.is_finite() {
                    continue;
                }
                let farther = |xx: usize, yy: usize| depth[yy * width + xx] > d + jump;
                let edge = (x > 0 && farther(x - 1, y))
                    || (x + 1 < width && farther(x + 1, y))
                    || (y > 0 && farther(x, y - 1))
                    || (y + 1 < height && farther(x, y + 1));
                if edge {
                    *c = c.map(|v| (f32::from(v) * OUTLINE).round() as u8);
                }
            }
        });
}

/// The samples averaged down to pixels (in linear light), the sky where none was drawn.
fn resolve(frame: &Frame, depth: &[f32], color: &[[u8; 3]]) -> Image {
    let (w, h, ss) = (frame.width, frame.height, frame.ss);
    let sw = w * ss;
    let mut rgb = vec![0u8; w * h * 3];
    rgb.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        let t = if h > 1 {
            y as f32 / (h - 1) as f32
        } else {
            0.0
        };
        let sky: [f32; 3] = std::array::from_fn(|k| {
            linear_of(SKY_TOP[k]) * (1.0 - t) + linear_of(SKY_BOTTOM[k]) * t
        });
        for x in 0..w {
            let mut sum = [0f32; 3];
            for sy in y * ss..(y + 1) * ss {
                for sx in x * ss..(x + 1) * ss {
                    let i = sy * sw + sx;
                    if depth[i].is_finite() {
                        for k in 0..3 {
                            sum[k] += linear_of(color[i][k]);
                        }
                    } else {
                        for k in 0..3 {
                            sum[k] += sky[k];
                        }
                    }
                }
            }
            let n = (ss * ss) as f32;
            for k in 0..3 {
                row[x * 3 + k] = linear_to_srgb(sum[k] / n);
            }
        }
    });
    Image {
        width: w as u32,
        height: h as u32,
        rgb,
    }
}

/// An 8-bit sRGB value as linear light, 0..=1 ([`srgb_u8_to_linear`], from a table).
fn linear_of(c: u8) -> f32 {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_u8_to_linear(i as u8)))[usize::from(c)]
}

/// Linear light (clamped to 0..=1, NaN as 0) as an 8-bit sRGB value.
pub(super) fn linear_to_srgb(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let c = if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0).round() as u8
}
