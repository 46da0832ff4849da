//! Openings of the IFC writer (LOD3): `IfcOpeningElement`s voiding their wall, filled by
//! `IfcWindow`s and `IfcDoor`s of shared `IfcWindowType`/`IfcDoorType`s.

use glam::{DVec2, DVec3};

use crate::color::material::Material;
use crate::color::Color;
use crate::export::step::{global_id, Id};
use crate::export::ExportError;
use crate::model::{rounded_rect, Opening, OpeningKind, Rounding, Wall};

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
    /// Rounded corners: (corners as bits top-left 1, top-right 2, bottom-right 4, bottom-left
    /// 8; radius in mm; segments; profile in thousandths).
    rounding: Option<(u8, i64, u32, i64)>,
    /// An explicit frame: (width, protrusion) in mm.
    frame: Option<(i64, i64)>,
}

impl TypeKey {
    /// The key of an opening in a wall of `thickness`; `None` if it is under a centimetre.
    fn of(o: &Opening, thickness: f64) -> Option<TypeKey> {
        let cm = |v: f64| (v * 100.0 + 1e-6).floor() as i64;
        let mm = |v: f64| (v.max(0.0) * 1000.0).round() as i64;
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
            rounding: o.rounding.filter(|r| r.is_rounded()).map(|r| {
                let bits = r
                    .corners
                    .iter()
                    .enumerate()
                    .fold(0u8, |b, (i, c)| if *c { b | 1 << i } else { b });
                (
                    bits,
                    mm(r.radius),
                    r.segments.clamp(1, Rounding::MAX_SEGMENTS),
                    (r.profile.clamp(0.0, 1.0) * 1000.0).round() as i64,
                )
            }),
            frame: o
                .frame_size
                .filter(|_| o.framed)
                .map(|f| (mm(f.width), mm(f.protrusion.clamp(0.0, 2.0)))),
        })
    }

    /// The rounding of the type's body, in metres.
    pub(super) fn rounding(&self) -> Option<Rounding> {
        self.rounding
            .map(|(bits, radius, segments, profile)| Rounding {
                corners: [bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0],
                radius: radius as f64 / 1000.0,
                segments,
                profile: profile as f64 / 1000.0,
            })
    }

    /// The explicit frame's (width, protrusion) in metres.
    pub(super) fn frame_size(&self) -> Option<(f64, f64)> {
        self.frame
            .map(|(w, p)| (w as f64 / 1000.0, p as f64 / 1000.0))
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
                "#{}",
                crate::fsio::hex(&[c(k[0]), c(k[1]), c(k[2]), c(k[3])])
            )
        };
        let mut name = format!(
            "{} {}x{} cm{}{} d{} {}/{}",
            if self.door { "Door" } else { "Window" },
            self.width_cm,
            self.height_cm,
            if self.framed { " framed" } else { "" },
            if self.glazed { " glazed" } else { "" },
            self.depth_mm,
            hex(self.color),
            hex(self.frame_color)
        );
        if let Some((bits, radius, segments, profile)) = self.rounding {
            name.push_str(&format!(
                " rounded {} r{radius}mm s{segments} p{profile}",
                corner_names(bits)
            ));
        }
        if let Some((w, p)) = self.frame {
            name.push_str(&format!(" frame {w}mm+{p}mm"));
        }
        name
    }
}

/// The rounded corners of a type's bits, e.g. `top_left,top_right` (the SELEX names).
fn corner_names(bits: u8) -> String {
    ["top_left", "top_right", "bottom_right", "bottom_left"]
        .iter()
        .enumerate()
        .filter(|(i, _)| bits & (1 << i) != 0)
        .map(|(_, n)| *n)
        .collect::<Vec<_>>()
        .join(",")
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
        let rounding = o.rounding.filter(|r| r.is_rounded());
        let rkey = rounding.map_or([0; 4], |r| {
            let bits = r
                .corners
                .iter()
                .enumerate()
                .fold(0i64, |b, (i, c)| if *c { b | 1 << i } else { b });
            [bits, q(r.radius), i64::from(r.segments), q(r.profile)]
        });
        let skey = [q(w), q(h), q(depth), rkey[0], rkey[1], rkey[2], rkey[3]];
        let body = match self.shared.opening_shapes.get(&skey) {
            Some(id) => id,
            None => {
                let (w, h, depth) = (
                    skey[0] as f64 / 1e6,
                    skey[1] as f64 / 1e6,
                    skey[2] as f64 / 1e6,
                );
                let profile = match rounding {
                    // The outline, from the opening's bottom-left corner.
                    Some(r) => {
                        let ring = rounded_rect(DVec2::ZERO, DVec2::new(w, h), Some(&r));
                        self.arbitrary_profile(&ring, &[])?
                    }
                    None => self.rect_profile(0.0, 0.0, w, h)?,
                };
                let solid = self.through_wall(profile, 0.0, depth)?;
                let body = self.shared_body(solid, "SweptSolid")?;
                self.shared.opening_shapes.insert(skey, body);
                body
            }
        };
        let shape = self.own_shape(body, "SweptSolid")?;
        let loc = DVec3::new(o.u0, -OPENING_TOLERANCE, o.z0 - wall.base_z);
        let pl = self.placement(wall_pl, loc, DVec3::X)?;
        let (name, ifc, predefined) = match o.kind {
            OpeningKind::Window => ("Window", "IFCWINDOW", "WINDOW"),
            OpeningKind::Door => ("Door", "IFCDOOR", "DOOR"),
        };
        let label = format!("{name} {}.{}", index.0, index.1);
        let opening = self.w.entity("IFCOPENINGELEMENT", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(&format!("Opening {}.{}", index.0, index.1))
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null();
            if self.g.schema.ifc4_attributes() {
                a.enumeration("OPENING");
            }
        })?;
        self.w.entity("IFCRELVOIDSELEMENT", |a| {
            a.guid(key, &format!("{path}/voids"))
                .opt_id(self.g.owner)
                .null()
                .null()
                .id(wall_id)
                .id(opening);
        })?;

        let type_shape = self.fill_type(&tkey)?;
        // The type's body is floored to the cm: centre it in the opening, and centre its
        // depth in the wall; a type with an explicit frame stands at the wall's outer face (its
        // frame stands out of it).
        let across = if tkey.frame.is_some() {
            0.0
        } else {
            (wall.thickness - tkey.depth()).max(0.0) / 2.0
        };
        let off = DVec3::new(
            (w - tkey.width()) / 2.0,
            OPENING_TOLERANCE + across,
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
                .opt_id(self.g.owner)
                .string(&label)
                .null()
                .null()
                .id(fill_pl)
                .id(type_shape)
                .null()
                .positive(h)
                .positive(w);
            if self.g.schema.ifc4_attributes() {
                a.enumeration(predefined);
                match o.kind {
                    OpeningKind::Window => a.enumeration("SINGLE_PANEL"),
                    OpeningKind::Door => a.enumeration("NOTDEFINED"),
                };
                a.null();
            }
        })?;
        self.w.entity("IFCRELFILLSELEMENT", |a| {
            a.guid(key, &format!("{path}/fills"))
                .opt_id(self.g.owner)
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
        if let Some((_, body)) = self.shared.types.get(k) {
            return self.own_shape(body, "MappedRepresentation");
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
        let rounding = k.rounding();
        let explicit = k.frame_size();
        let fw = explicit
            .map_or(FRAME_WIDTH, |(fw, _)| fw)
            .min(w.min(h) / 4.0);
        // A rounded or explicitly sized frame is drawn from its outlines; the standard frame
        // of a rectangle is a hollow rectangle.
        let outlines = rounding.is_some() || explicit.is_some();
        let inner = |inset: f64| {
            let r = rounding.map(|r| Rounding {
                radius: (r.radius - inset).max(0.0),
                ..r
            });
            rounded_rect(
                DVec2::new(inset, inset),
                DVec2::new(w - inset, h - inset),
                r.as_ref(),
            )
        };
        let inset = if k.framed && fw > 0.0 {
            let profile = if outlines {
                self.arbitrary_profile(&inner(0.0), &[inner(fw)])?
            } else {
                let centre = self.point2(DVec2::new(w / 2.0, h / 2.0))?;
                let pos = self.w.entity("IFCAXIS2PLACEMENT2D", |a| {
                    a.id(centre).null();
                })?;
                self.w.entity("IFCRECTANGLEHOLLOWPROFILEDEF", |a| {
                    a.enumeration("AREA")
                        .null()
                        .id(pos)
                        .positive(w)
                        .positive(h)
                        .positive(fw)
                        .null()
                        .null();
                })?
            };
            // An explicit frame stands out of the wall's face by its protrusion.
            let protrusion = explicit.map_or(0.0, |(_, p)| p);
            let frame = self.through_wall(profile, -protrusion, d + protrusion)?;
            self.rendered(
                frame,
                color(k.frame_color),
                alpha_transparency(k.frame_color),
                Material::Unspecified,
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
        let profile = if rounding.is_some() {
            self.arbitrary_profile(&inner(inset), &[])?
        } else {
            self.rect_profile(inset, inset, w - 2.0 * inset, h - 2.0 * inset)?
        };
        let panel = self.through_wall(profile, (d - pane) / 2.0, pane)?;
        let transparency = if k.glazed {
            GLASS_TRANSPARENCY
        } else {
            alpha_transparency(k.color)
        };
        // Glass where the other writers draw glass: a glazed window's pane.
        let material = Material::of_pane(k.glazed && !k.door);
        self.rendered(panel, color(k.color), transparency, material)?;
        items.push(panel);

        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let identity = self.g.identity;
        let map = self.w.entity("IFCREPRESENTATIONMAP", |a| {
            a.id(identity).id(rep);
        })?;
        let name = k.name();
        let gid = global_id(&self.g.ns, &format!("type/{name}"));
        let psets = self.type_psets(k, &name, fw, d)?;
        let schema = self.g.schema;
        let id = self.w.entity(schema.fill_type(k.door), |a| {
            a.string(&gid)
                .opt_id(self.g.owner)
                .string(&name)
                .null()
                .null();
            if psets.is_empty() {
                a.null();
            } else {
                a.ids(&psets);
            }
            a.ids(&[map]).null();
            match (schema.ifc4_attributes(), k.door) {
                (true, true) => {
                    a.null().enumeration("DOOR");
                    a.enumeration("NOTDEFINED").boolean(false).null()
                }
                (true, false) => {
                    a.null().enumeration("WINDOW");
                    a.enumeration("SINGLE_PANEL").boolean(false).null()
                }
                // IFC2X3's IfcDoorStyle: OperationType, ConstructionType, ...
                (false, true) => a.enumeration("NOTDEFINED").enumeration("NOTDEFINED"),
                // ... and IfcWindowStyle: ConstructionType, OperationType, ...
                (false, false) => a.enumeration("NOTDEFINED").enumeration("SINGLE_PANEL"),
            };
            if !schema.ifc4_attributes() {
                // ParameterTakesPrecedence, Sizeable.
                a.boolean(false).boolean(false);
            }
        })?;
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
        let body = self.shared_body(mapped, "MappedRepresentation")?;
        self.shared.types.insert(*k, (id, body));
        self.own_shape(body, "MappedRepresentation")
    }

    /// What a body shared by several products is cached as: the product shape of a `Body`
    /// representation (`kind`) of `item`, or in IFC2X3, where a product shape and its
    /// representation belong to one product only, the item itself ([`Self::own_shape`]).
    fn shared_body(&mut self, item: Id, kind: &str) -> Result<Id, ExportError> {
        if !self.g.schema.shared_shapes() {
            return Ok(item);
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", kind, &[item])?;
        self.shape(&[rep])
    }

    /// The product shape of one product from a cached shared body ([`Self::shared_body`]):
    /// the shared product shape, or in IFC2X3 a representation and product shape of its own.
    fn own_shape(&mut self, body: Id, kind: &str) -> Result<Id, ExportError> {
        if self.g.schema.shared_shapes() {
            return Ok(body);
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", kind, &[body])?;
        self.shape(&[rep])
    }

    /// The property sets a window or door type carries beyond the standard ones (none for
    /// those): for an explicit frame the `IfcWindowLiningProperties` or
    /// `IfcDoorLiningProperties` (lining depth: the frame's depth and protrusion; lining
    /// thickness: its width `fw`), and for rounded corners or an explicit frame a
    /// `Citygen_OpeningShape` set with the SELEX parameters (RoundedCorners, CornerRadius,
    /// ArcSegments, CornerProfile; FrameWidth, FrameProtrusion).
    fn type_psets(
        &mut self,
        k: &TypeKey,
        name: &str,
        fw: f64,
        d: f64,
    ) -> Result<Vec<Id>, ExportError> {
        let mut psets = Vec::new();
        let mut props = Vec::new();
        let single = |w: &mut crate::export::step::StepBuf,
                      prop: &str,
                      ty: &str,
                      f: &dyn Fn(&mut crate::export::step::Args<'_>)| {
            w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                a.string(prop).null().typed(ty, |t| f(t)).null();
            })
        };
        if let Some((bits, _, segments, _)) = k.rounding {
            let r = k.rounding().map_or(0.0, |r| r.radius);
            let p = k.rounding().map_or(0.5, |r| r.profile);
            let corners = corner_names(bits);
            props.push(single(&mut self.w, "RoundedCorners", "IFCLABEL", &|t| {
                t.string(&corners);
            })?);
            props.push(single(
                &mut self.w,
                "CornerRadius",
                "IFCPOSITIVELENGTHMEASURE",
                &|t| {
                    t.positive(r.max(0.001));
                },
            )?);
            props.push(single(&mut self.w, "ArcSegments", "IFCINTEGER", &|t| {
                t.int(i64::from(segments));
            })?);
            props.push(single(
                &mut self.w,
                "CornerProfile",
                "IFCNORMALISEDRATIOMEASURE",
                &|t| {
                    t.real(p);
                },
            )?);
        }
        if let Some((_, protrusion)) = k.frame_size().filter(|_| k.framed && fw > 0.0) {
            props.push(single(
                &mut self.w,
                "FrameWidth",
                "IFCPOSITIVELENGTHMEASURE",
                &|t| {
                    t.positive(fw);
                },
            )?);
            props.push(single(
                &mut self.w,
                "FrameProtrusion",
                "IFCLENGTHMEASURE",
                &|t| {
                    t.real(protrusion);
                },
            )?);
            let gid = global_id(&self.g.ns, &format!("type/{name}/lining"));
            let lining = if k.door {
                self.w.entity("IFCDOORLININGPROPERTIES", |a| {
                    a.string(&gid).opt_id(self.g.owner).string("Frame").null();
                    a.positive(d + protrusion).positive(fw);
                    for _ in 0..self.g.schema.lining_tail(true) {
                        a.null();
                    }
                })?
            } else {
                self.w.entity("IFCWINDOWLININGPROPERTIES", |a| {
                    a.string(&gid).opt_id(self.g.owner).string("Frame").null();
                    a.positive(d + protrusion).positive(fw);
                    for _ in 0..self.g.schema.lining_tail(false) {
                        a.null();
                    }
                })?
            };
            psets.push(lining);
        }
        if !props.is_empty() {
            let gid = global_id(&self.g.ns, &format!("type/{name}/shape"));
            psets.push(self.w.entity("IFCPROPERTYSET", |a| {
                a.string(&gid)
                    .opt_id(self.g.owner)
                    .string("Citygen_OpeningShape")
                    .null()
                    .ids(&props);
            })?);
        }
        Ok(psets)
    }
}
