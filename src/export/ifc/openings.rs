//! Openings of the IFC writer (LOD3): `IfcOpeningElement`s voiding their wall, filled by
//! `IfcWindow`s and `IfcDoor`s of shared `IfcWindowType`/`IfcDoorType`s.

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::export::step::{global_id, Id};
use crate::export::ExportError;
use crate::model::{Opening, OpeningKind, Wall};

use super::styles::color_key;
use super::{
    Render, FRAME_DEPTH, FRAME_WIDTH, GLASS_THICKNESS, GLASS_TRANSPARENCY, OPENING_TOLERANCE,
    PANEL_THICKNESS,
};

/// What makes two windows or doors share a type: kind, size (floored to the cm), frame depth
/// (mm), glazing, frame, colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct TypeKey {
    door: bool,
    width_cm: i64,
    height_cm: i64,
    depth_mm: i64,
    glazed: bool,
    framed: bool,
    color: [u16; 4],
    frame_color: [u16; 4],
}

impl TypeKey {
    /// The key of an opening in a wall of `thickness`; `None` if it is under a centimetre.
    fn of(o: &Opening, thickness: f64) -> Option<TypeKey> {
        let cm = |v: f64| (v * 100.0 + 1e-6).floor() as i64;
        let (width_cm, height_cm) = (cm(o.width()), cm(o.height()));
        let depth_mm = (FRAME_DEPTH.min(thickness) * 1000.0).round() as i64;
        (width_cm >= 1 && height_cm >= 1 && depth_mm >= 1).then_some(TypeKey {
            door: o.kind == OpeningKind::Door,
            width_cm,
            height_cm,
            depth_mm,
            glazed: o.glazed,
            framed: o.framed,
            color: color_key(o.color),
            frame_color: color_key(o.frame_color),
        })
    }

    pub(super) fn width(&self) -> f64 {
        self.width_cm as f64 / 100.0
    }

    pub(super) fn height(&self) -> f64 {
        self.height_cm as f64 / 100.0
    }

    pub(super) fn depth(&self) -> f64 {
        self.depth_mm as f64 / 1000.0
    }

    /// A readable, unique name (also the GlobalId path of the type).
    pub(super) fn name(&self) -> String {
        let hex = |k: [u16; 4]| {
            let c = |v: u16| (f64::from(v) / 1000.0 * 255.0).round() as u8;
            format!(
                "#{:02x}{:02x}{:02x}{:02x}",
                c(k[0]),
                c(k[1]),
                c(k[2]),
                c(k[3])
            )
        };
        format!(
            "{} {}x{} cm{}{} d{} {}/{}",
            if self.door { "Door" } else { "Window" },
            self.width_cm,
            self.height_cm,
            if self.framed { " framed" } else { "" },
            if self.glazed { " glazed" } else { "" },
            self.depth_mm,
            hex(self.color),
            hex(self.frame_color)
        )
    }
}

/// The wall an opening is cut into, as written: the model's wall, its `IfcWallStandardCase`
/// and the wall's local placement.
#[derive(Clone, Copy)]
pub(super) struct Host<'a> {
    pub(super) wall: &'a Wall,
    pub(super) id: Id,
    pub(super) placement: Id,
}

impl Render<'_> {
    /// One opening of `wall`: an `IfcOpeningElement` voiding the wall, filled by an `IfcWindow`
    /// or `IfcDoor` of a shared type. Returns the window or door (to be contained in the
    /// wall's storey), or `None` for an opening too small to build (nothing written then).
    pub(super) fn opening(
        &mut self,
        host: &Host<'_>,
        o: &Opening,
        key: &str,
        path: &str,
        index: (usize, usize),
    ) -> Result<Option<Id>, ExportError> {
        let Host {
            wall,
            id: wall_id,
            placement: wall_pl,
        } = *host;
        let (w, h) = (o.width(), o.height());
        let Some(tkey) = TypeKey::of(o, wall.thickness) else {
            return Ok(None);
        };
        let q = |v: f64| (v * 1e6).round() as i64;
        let depth = wall.thickness + 2.0 * OPENING_TOLERANCE;
        let skey = [q(w), q(h), q(depth)];
        let shape = match self.shared.opening_shapes.get(&skey) {
            Some(id) => id,
            None => {
                let (w, h, depth) = (
                    skey[0] as f64 / 1e6,
                    skey[1] as f64 / 1e6,
                    skey[2] as f64 / 1e6,
                );
                let profile = self.rect_profile(0.0, 0.0, w, h)?;
                let solid = self.through_wall(profile, 0.0, depth)?;
                let body_ctx = self.g.body_ctx;
                let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
                let shape = self.shape(&[rep])?;
                self.shared.opening_shapes.insert(skey, shape);
                shape
            }
        };
        let loc = DVec3::new(o.u0, -OPENING_TOLERANCE, o.z0 - wall.base_z);
        let pl = self.placement(wall_pl, loc, DVec3::X)?;
        let (name, ifc, predefined) = match o.kind {
            OpeningKind::Window => ("Window", "IFCWINDOW", "WINDOW"),
            OpeningKind::Door => ("Door", "IFCDOOR", "DOOR"),
        };
        let label = format!("{name} {}.{}", index.0, index.1);
        let opening = self.w.entity("IFCOPENINGELEMENT", |a| {
            a.guid(key, path)
                .null()
                .string(&format!("Opening {}.{}", index.0, index.1))
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("OPENING");
        })?;
        self.w.entity("IFCRELVOIDSELEMENT", |a| {
            a.guid(key, &format!("{path}/voids"))
                .null()
                .null()
                .null()
                .id(wall_id)
                .id(opening);
        })?;

        let type_shape = self.fill_type(&tkey)?;
        // The type's body is floored to the cm: centre it in the opening, and centre its
        // depth in the wall.
        let off = DVec3::new(
            (w - tkey.width()) / 2.0,
            OPENING_TOLERANCE + (wall.thickness - tkey.depth()).max(0.0) / 2.0,
            (h - tkey.height()) / 2.0,
        );
        let okey = [q(off.x), q(off.y), q(off.z)];
        let axes = match self.shared.fill_offsets.get(&okey) {
            Some(id) => id,
            None => {
                let p = DVec3::new(okey[0] as f64, okey[1] as f64, okey[2] as f64) / 1e6;
                let id = self.axes(p, DVec3::X)?;
                self.shared.fill_offsets.insert(okey, id);
                id
            }
        };
        let fill_pl = self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(pl).id(axes);
        })?;
        let fill = self.w.entity(ifc, |a| {
            a.guid(key, &format!("{path}/fill"))
                .null()
                .string(&label)
                .null()
                .null()
                .id(fill_pl)
                .id(type_shape)
                .null()
                .positive(h)
                .positive(w)
                .enumeration(predefined);
            match o.kind {
                OpeningKind::Window => a.enumeration("SINGLE_PANEL"),
                OpeningKind::Door => a.enumeration("NOTDEFINED"),
            };
            a.null();
        })?;
        self.w.entity("IFCRELFILLSELEMENT", |a| {
            a.guid(key, &format!("{path}/fills"))
                .null()
                .null()
                .null()
                .id(opening)
                .id(fill);
        })?;
        self.occurrences.push((tkey, fill));
        Ok(Some(fill))
    }

    /// The shape shared by every occurrence of a window or door type (an `IfcMappedItem` of its
    /// representation map), writing the type on first use.
    ///
    /// The type's body, in its local frame (X along the width, Y across the wall, Z up, all
    /// from 0): a framed opening has a frame (a hollow rectangle, `FRAME_DEPTH` deep) and a
    /// glass pane or door panel in the middle of it; an unframed one is a single pane or panel.
    fn fill_type(&mut self, k: &TypeKey) -> Result<Id, ExportError> {
        if let Some((_, shape)) = self.shared.types.get(k) {
            return Ok(shape);
        }
        let (w, h, d) = (k.width(), k.height(), k.depth());
        let color = |c: [u16; 4]| {
            let f = |v: u16| f64::from(v) as f32 / 1000.0;
            Color {
                r: f(c[0]),
                g: f(c[1]),
                b: f(c[2]),
                a: f(c[3]),
            }
        };
        let alpha_transparency = |c: [u16; 4]| 1.0 - f64::from(c[3]) / 1000.0;
        let mut items = Vec::new();
        let fw = FRAME_WIDTH.min(w.min(h) / 4.0);
        let inset = if k.framed {
            let centre = self.point2(DVec2::new(w / 2.0, h / 2.0))?;
            let pos = self.w.entity("IFCAXIS2PLACEMENT2D", |a| {
                a.id(centre).null();
            })?;
            let profile = self.w.entity("IFCRECTANGLEHOLLOWPROFILEDEF", |a| {
                a.enumeration("AREA")
                    .null()
                    .id(pos)
                    .positive(w)
                    .positive(h)
                    .positive(fw)
                    .null()
                    .null();
            })?;
            let frame = self.through_wall(profile, 0.0, d)?;
            self.rendered(
                frame,
                color(k.frame_color),
                alpha_transparency(k.frame_color),
            )?;
            items.push(frame);
            fw
        } else {
            0.0
        };
        let pane = if k.door {
            PANEL_THICKNESS
        } else {
            GLASS_THICKNESS
        }
        .min(d);
        let profile = self.rect_profile(inset, inset, w - 2.0 * inset, h - 2.0 * inset)?;
        let panel = self.through_wall(profile, (d - pane) / 2.0, pane)?;
        let transparency = if k.glazed {
            GLASS_TRANSPARENCY
        } else {
            alpha_transparency(k.color)
        };
        self.rendered(panel, color(k.color), transparency)?;
        items.push(panel);

        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let identity = self.g.identity;
        let map = self.w.entity("IFCREPRESENTATIONMAP", |a| {
            a.id(identity).id(rep);
        })?;
        let name = k.name();
        let gid = global_id(&self.g.ns, &format!("type/{name}"));
        let id = if k.door {
            self.w.entity("IFCDOORTYPE", |a| {
                a.string(&gid).null().string(&name).null().null().null();
                a.ids(&[map]).null().null().enumeration("DOOR");
                a.enumeration("NOTDEFINED").boolean(false).null();
            })?
        } else {
            self.w.entity("IFCWINDOWTYPE", |a| {
                a.string(&gid).null().string(&name).null().null().null();
                a.ids(&[map]).null().null().enumeration("WINDOW");
                a.enumeration("SINGLE_PANEL").boolean(false).null();
            })?
        };
        let op = match self.shared.identity_op.get(&()) {
            Some(op) => op,
            None => {
                let o = self.g.origin3;
                let op = self.w.entity("IFCCARTESIANTRANSFORMATIONOPERATOR3D", |a| {
                    a.null().null().id(o).null().null();
                })?;
                self.shared.identity_op.insert((), op);
                op
            }
        };
        let mapped = self.w.entity("IFCMAPPEDITEM", |a| {
            a.id(map).id(op);
        })?;
        let rep = self.representation(body_ctx, "Body", "MappedRepresentation", &[mapped])?;
        let shape = self.shape(&[rep])?;
        self.shared.types.insert(*k, (id, shape));
        Ok(shape)
    }
}
