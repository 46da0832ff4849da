//! An overview picture of a city, rendered in software and written as PNG: what a nightly job
//! publishes to show what it made, with no browser and no GPU.
//!
//! Two sources feed one [`Scene`] (coloured triangles in a metric frame: x east, y north, z up,
//! metres):
//! - [`PreviewWriter`], a [`BuildingWriter`] of a run (`--preview OUT.png`): each building's
//!   triangles exactly as the glTF writer draws them (the same faces, triangulation and faces
//!   left out between parts; walls and roofs, and at LOD3 windows, doors and balconies), in the
//!   run's local frame;
//! - [`glb_triangles`], a reader of glTF 2.0 binaries (a region's 3D Tiles contents, `citygen
//!   merge --preview`), whose caller maps each point into the common frame.
//!
//! [`Scene::render`] draws the scene as a bird's-eye view ([`View`]): orthographic, 45° down,
//! from the side that lays the scene's plan across the picture (its longer axis along the
//! picture's width, the camera in the southern half) unless a bearing is given, fitted to the
//! scene's bounds with a margin, on a ground plate that ends in a horizon under a sky
//! gradient; a z-buffer, flat Lambert shading with a sun fixed relative to the camera plus sky
//! and ambient light (so roofs and the two sides of a building read apart), dark outlines where
//! the depth jumps (so buildings read apart from each other), supersampled and averaged down.
//! The picture is a pure function of the scene's triangles in order and the view (each sample
//! is drawn by one task, triangle by triangle in order), whatever the thread count.
//!
//! Memory: the writer cannot frame the picture before it has seen the last building (a
//! [`BuildingWriter`] is not told the run's extent), so it keeps the triangles until `finish`,
//! compactly: `f32` positions, vertices shared within a primitive (welded by their bits), `u16`
//! indices, one colour a primitive. Monaco at LOD2 takes 560 bytes a building (28 triangles,
//! 27 vertices), so 100,000 such buildings some 60 MB; the picture's own buffers are 7 bytes a
//! sample, 45 MB at the default size (1600 x 1000, supersampled 2 x 2). To keep one picture
//! of a run written in tiles, keep one [`Scene`] across them (`Scene::add_building`) and
//! render it at the end.
//!
//! Code layout: this module holds the scene and the writer, `raster` the camera, rasterizer
//! and shading, `png` the PNG encoder, `glb` the glTF reader.

use std::collections::HashMap;
use std::io::Write;

use rayon::prelude::*;

use crate::color::Color;
use crate::export::{BuildingWriter, Checked, ExportError, OutputContext};
use crate::model::{Building, Lod};

mod glb;
use crate::export::png;
mod raster;

pub use glb::{glb_triangles, GlbError, GlbMesh, MAX_VERTICES};

/// How a scene is drawn: picture size and camera.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Picture width in pixels (1 to `MAX_SIDE`; outside, clamped).
    pub width: u32,
    /// Picture height in pixels (1 to `MAX_SIDE`; outside, clamped).
    pub height: u32,
    /// The compass bearing the camera looks towards, degrees clockwise from north (22.5 looks
    /// north-north-east, from the south-south-west). `None`: square to the scene plan's longer
    /// axis, from its southern side, so that the plan lies across the picture.
    pub azimuth: Option<f64>,
    /// How far the camera looks down, degrees below the horizon (clamped to 5..=90).
    pub elevation: f64,
    /// Samples per pixel along each axis (1 to 4; the sample buffers are kept under
    /// `MAX_SAMPLES` by lowering it).
    pub supersample: u32,
    /// The empty border around the scene, as a fraction of the picture's smaller side.
    pub margin: f64,
    /// Whether a ground plate is drawn under the scene (its plan bounds plus a border).
    pub ground: bool,
}

impl Default for View {
    fn default() -> View {
        View {
            width: 1600,
            height: 1000,
            azimuth: None,
            elevation: 45.0,
            supersample: 2,
            margin: 0.04,
            ground: true,
        }
    }
}

/// The largest picture side [`Scene::render`] draws.
pub(crate) const MAX_SIDE: u32 = 8192;

/// The most samples (pixels times supersampling squared) a render holds: 7 bytes each.
pub(crate) const MAX_SAMPLES: u64 = 1 << 26;

/// A rendered picture: 8-bit sRGB, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Image {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, 3 bytes (r, g, b) each, row by row from the top.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The picture as a PNG file (deterministic bytes).
    pub fn to_png(&self) -> Vec<u8> {
        // An Image's sides are 1..=MAX_SIDE and its buffer their product: always encodable.
        png::encode_rgb(self.width, self.height, &self.rgb).unwrap_or_default()
    }
}

/// Coloured triangles in one metric frame (x east, y north, z up, metres), kept compactly for
/// rendering: see the module documentation.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Vertices of every run, run after run.
    positions: Vec<[f32; 3]>,
    /// Triangles of every run, as indices into the run's own vertices.
    triangles: Vec<[u16; 3]>,
    runs: Vec<Run>,
}

/// Triangles of one colour sharing up to 65,536 vertices.
#[derive(Clone, Copy, Debug)]
struct Run {
    /// The run's first vertex in `Scene::positions`.
    first_vertex: usize,
    /// The run's triangles: `Scene::triangles[first_triangle..end_triangle]`.
    first_triangle: usize,
    end_triangle: usize,
    color: [u8; 3],
}

impl Scene {
    /// An empty scene.
    pub fn new() -> Scene {
        Scene::default()
    }

    /// Adds triangles of one colour (sRGB, 8 bits a channel): `indices` in threes into
    /// `positions`. Triangles with an index out of range or a non-finite coordinate are left
    /// out, as is a trailing incomplete triangle; vertices are welded by their exact bits.
    pub fn add(&mut self, color: [u8; 3], positions: &[[f32; 3]], indices: &[u32]) {
        let mut welded: HashMap<[u32; 3], u16> = HashMap::new();
        let mut run = Run {
            first_vertex: self.positions.len(),
            first_triangle: self.triangles.len(),
            end_triangle: self.triangles.len(),
            color,
        };
        for t in indices.chunks_exact(3) {
            let Some(corners) = t
                .iter()
                .map(|&i| positions.get(i as usize).copied())
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            if corners.iter().flatten().any(|c| !c.is_finite()) {
                continue;
            }
            // Room for three new vertices, else a new run.
            if self.positions.len() - run.first_vertex + 3 > usize::from(u16::MAX) + 1 {
                self.close(&mut run, &mut welded);
            }
            let mut tri = [0u16; 3];
            for (k, p) in corners.iter().enumerate() {
                let key = p.map(|c| (c + 0.0).to_bits());
                tri[k] = *welded.entry(key).or_insert_with(|| {
                    self.positions.push(*p);
                    // In range: the run holds at most 65,536 vertices.
                    (self.positions.len() - 1 - run.first_vertex) as u16
                });
            }
            self.triangles.push(tri);
        }
        self.close(&mut run, &mut welded);
    }

    /// Ends `run` (kept if it has triangles) and starts the next one after it.
    fn close(&mut self, run: &mut Run, welded: &mut HashMap<[u32; 3], u16>) {
        run.end_triangle = self.triangles.len();
        if run.end_triangle > run.first_triangle {
            self.runs.push(*run);
        }
        welded.clear();
        run.first_vertex = self.positions.len();
        run.first_triangle = self.triangles.len();
    }

    /// Adds what [`glb_triangles`] read.
    pub fn add_glb_meshes(&mut self, meshes: &[GlbMesh]) {
        for m in meshes {
            let positions: Vec<[f32; 3]> =
                m.positions.iter().map(|p| p.map(|c| c as f32)).collect();
            self.add(m.color, &positions, &m.indices);
        }
    }

    /// Adds a building as its glTF is drawn (see the module documentation); `detail`: its
    /// LOD3 windows, doors and balconies too. A building with a non-finite coordinate is
    /// refused, as every writer refuses it.
    pub(crate) fn add_building(&mut self, b: &Building, detail: bool) -> Result<(), ExportError> {
        let mut meshes = Vec::new();
        building_meshes(b, detail, &mut meshes)?;
        for (color, positions, indices) in &meshes {
            self.add(*color, positions, indices);
        }
        Ok(())
    }

    /// The number of triangles held.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The number of (welded) vertices held.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The bytes the scene's buffers take (their capacity).
    pub fn heap_bytes(&self) -> usize {
        self.positions.capacity() * std::mem::size_of::<[f32; 3]>()
            + self.triangles.capacity() * std::mem::size_of::<[u16; 3]>()
            + self.runs.capacity() * std::mem::size_of::<Run>()
    }

    /// The axis-aligned bounds of the scene's vertices (min, max), `None` when it is empty.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        raster::bounds(self)
    }

    /// Draws the scene (see the module documentation). An empty scene gives the sky alone.
    pub fn render(&self, view: &View) -> Image {
        raster::render(self, view)
    }
}

/// One building's primitives as (colour, positions, indices), appended to `out`.
type Mesh = ([u8; 3], Vec<[f32; 3]>, Vec<u32>);

fn building_meshes(b: &Building, detail: bool, out: &mut Vec<Mesh>) -> Result<(), ExportError> {
    crate::export::gltf::outside_triangles(b, detail, |color, positions, indices| {
        out.push((to_rgb8(color), positions.to_vec(), indices.to_vec()));
    })
}

/// An sRGB colour in 0..=1 as 8-bit channels (alpha dropped: the picture draws every surface
/// opaque).
fn to_rgb8(c: Color) -> [u8; 3] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.r), q(c.g), q(c.b)]
}

/// Where the writer is in its `begin` / `write` / `finish` life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    New,
    Open,
    Finished,
}

/// A [`BuildingWriter`] that draws the run's buildings into one PNG picture at `finish` (see
/// the module documentation). Nothing is written to `out` before `finish`.
pub struct PreviewWriter<W: Write + Send> {
    out: W,
    view: View,
    scene: Scene,
    /// Whether the run is LOD3 or above (openings and balconies are drawn).
    detail: bool,
    state: State,
}

impl<W: Write + Send> PreviewWriter<W> {
    /// A writer of the picture to `out`, with the default [`View`].
    pub fn new(out: W) -> PreviewWriter<W> {
        PreviewWriter {
            out,
            view: View::default(),
            scene: Scene::new(),
            detail: false,
            state: State::New,
        }
    }

    /// The same writer drawing with `view`.
    #[cfg(test)]
    pub(crate) fn with_view(mut self, view: View) -> PreviewWriter<W> {
        self.view = view;
        self
    }

    /// The triangles collected so far.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Gives back the output (the PNG after a successful `finish`).
    pub fn into_inner(self) -> W {
        self.out
    }

    fn open(&self) -> Result<(), ExportError> {
        match self.state {
            State::Open => Ok(()),
            State::New => Err(ExportError::Invalid(
                "preview writer: write called before begin".into(),
            )),
            State::Finished => Err(ExportError::Invalid(
                "preview writer: write called after finish".into(),
            )),
        }
    }
}

impl<W: Write + Send> BuildingWriter for PreviewWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        if self.state != State::New {
            return Err(ExportError::Invalid(
                "preview writer: begin called twice".into(),
            ));
        }
        self.detail = ctx.lod >= Lod::Lod3;
        self.state = State::Open;
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        self.open()?;
        self.scene.add_building(building, self.detail)
    }

    /// Triangulates `super::PARALLEL_BATCH` buildings at a time in parallel and adds them in
    /// order: the same scene as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.open()?;
        let detail = self.detail;
        for batch in buildings.chunks(super::PARALLEL_BATCH) {
            let meshes: Vec<Result<Vec<Mesh>, ExportError>> = batch
                .par_iter()
                .map(|b| {
                    let mut m = Vec::new();
                    building_meshes(b, detail, &mut m).map(|()| m)
                })
                .collect();
            for m in meshes {
                for (color, positions, indices) in &m? {
                    self.scene.add(*color, positions, indices);
                }
            }
        }
        Ok(())
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        self.write_all(checked.finite())?;
        checked.refused("preview writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        match self.state {
            State::Open => {}
            State::New => {
                return Err(ExportError::Invalid(
                    "preview writer: finish called before begin".into(),
                ))
            }
            State::Finished => {
                return Err(ExportError::Invalid(
                    "preview writer: finish called twice".into(),
                ))
            }
        }
        self.state = State::Finished;
        let png = self.scene.render(&self.view).to_png();
        // The scene is no longer needed: give its memory back before the file is flushed.
        self.scene = Scene::new();
        self.out.write_all(&png)?;
        self.out.flush()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
