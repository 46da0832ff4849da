//! LOD4 additions of the IFC writer: a part's interiors ([`Part::interior`]) in its LOD3 storeys.
//!
//! Per [`StoreyInterior`], in the `IfcBuildingStorey` of its `storey`:
//!
//! - one `IfcSpace` `.SPACE.` per room (Name = the room's name, LongName = its usage), whose
//!   `Body` is the room polygon extruded from the floor to the ceiling (`SweptSolid`), with an
//!   `IfcElementQuantity` `Qto_SpaceBaseQuantities` (NetFloorArea, GrossPerimeter, Height,
//!   NetVolume); the storey aggregates its spaces (`IfcRelAggregates`);
//! - one `IfcWallStandardCase` `.PARTITIONING.` per interior wall: a rectangle profile centred
//!   on the wall's centre line (the element is placed half its thickness to the right of the
//!   line, so that its body spans +Y from 0 to the thickness like the exterior walls), extruded
//!   from the floor to the ceiling, with an `Axis`, the shared `IfcMaterialLayerSetUsage` of its
//!   thickness and a `Pset_WallCommon` with IsExternal false;
//! - one `IfcOpeningElement` per interior door voiding its wall, filled by an `IfcDoor` of a
//!   shared `IfcDoorType` (the LOD3 machinery: same type key, mapped item, placement centred in
//!   the wall), from [`lod4geom::DOOR_SILL`] above the floor;
//! - an `IfcStair` `.STRAIGHT_RUN_STAIR.` when the storey has a stair: one extruded block per
//!   step ([`lod4geom::stair_steps`]);
//! - above the ground storey, an `IfcSlab` `.FLOOR.`: the rooms minus the well of the stair
//!   coming up from the storey below, extruded down by the slab thickness from the floor (it
//!   is also the ceiling of the storey below).
//!
//! Everything but the spaces is contained in the storey with the LOD3 elements.

use std::collections::BTreeMap;
use std::io::Write;

use glam::{DVec2, DVec3};

use super::{ElementFrame, Open, EPS};
use crate::export::lod4geom;
use crate::export::step::{global_id, Id};
use crate::export::ExportError;
use crate::model::{Face, Opening, OpeningKind, Part, StoreyInterior, Wall};

impl<W: Write> Open<W> {
    /// Writes the interiors of `part` into its storeys (`storeys[i]` placed by `frames[i]`),
    /// adding the contained elements to `contained[i]` and the interior walls to `by_usage`.
    pub(super) fn interiors(
        &mut self,
        part: &Part,
        key: &str,
        storeys: &[Id],
        frames: &[ElementFrame],
        contained: &mut [Vec<Id>],
        by_usage: &mut BTreeMap<Id, Vec<Id>>,
    ) -> Result<(), ExportError> {
        let pk = &part.key;
        let mut partitions = Vec::new();
        for (k, s) in part.interior.iter().enumerate() {
            let i = s.storey;
            if !(s.floor_z.is_finite() && s.ceiling_z.is_finite()) {
                continue;
            }
            let (Some(&storey), Some(frame)) = (storeys.get(i), frames.get(i)) else {
                continue;
            };
            let path = format!("{pk}/interior/{i}");
            // Spaces, aggregated under the storey.
            let mut spaces = Vec::with_capacity(s.rooms.len());
            for r in 0..s.rooms.len() {
                if let Some(id) = self.space(s, r, frame, key, &format!("{path}/space/{r}"))? {
                    spaces.push(id);
                }
            }
            if !spaces.is_empty() {
                self.w.entity("IFCRELAGGREGATES", |a| {
                    a.string(&global_id(key, &format!("{path}/spaces")))
                        .null()
                        .null()
                        .null()
                        .id(storey)
                        .ids(&spaces);
                })?;
            }
            // Interior walls and their doors.
            for (wi, w) in s.walls.iter().enumerate() {
                let wpath = format!("{path}/wall/{wi}");
                let Some((wall, id, pl)) = self.partition(s, wi, frame, key, &wpath)? else {
                    continue;
                };
                let usage = self.usage(w.thickness)?;
                by_usage.entry(usage).or_default().push(id);
                partitions.push(id);
                contained[i].push(id);
                for (di, d) in s.doors.iter().enumerate().filter(|(_, d)| d.wall == wi) {
                    let Some((z0, z1)) = lod4geom::door_heights(s, d) else {
                        continue;
                    };
                    if !(d.u0 > 0.0 && d.u1 <= wall.length() && d.u1 - d.u0 > 0.01) {
                        continue;
                    }
                    let o = Opening {
                        kind: OpeningKind::Door,
                        u0: d.u0,
                        u1: d.u1,
                        z0,
                        z1,
                        color: lod4geom::DOOR_COLOR,
                        frame_color: lod4geom::DOOR_FRAME_COLOR,
                        glazed: false,
                        framed: true,
                    };
                    let dpath = format!("{path}/door/{di}");
                    if let Some(fill) = self.opening(&wall, id, pl, &o, key, &dpath, (wi, di))? {
                        contained[i].push(fill);
                    }
                }
            }
            if let Some(st) = &s.stair {
                if let Some(id) = self.stair(s, st, frame, key, &format!("{path}/stair"))? {
                    contained[i].push(id);
                }
            }
            let below = k
                .checked_sub(1)
                .and_then(|b| part.interior.get(b))
                .filter(|b| b.storey + 1 == i);
            if let Some(id) = self.floor(below, s, frame, key, &format!("{path}/slab"))? {
                contained[i].push(id);
            }
        }
        if !partitions.is_empty() {
            let prop = self.w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                a.string("IsExternal").null().typed("IFCBOOLEAN", |t| {
                    t.boolean(false);
                });
                a.null();
            })?;
            let pset = self.w.entity("IFCPROPERTYSET", |a| {
                a.string(&global_id(key, &format!("{pk}/partitions/pset")))
                    .null()
                    .string("Pset_WallCommon")
                    .null()
                    .ids(&[prop]);
            })?;
            self.w.entity("IFCRELDEFINESBYPROPERTIES", |a| {
                a.string(&global_id(key, &format!("{pk}/partitions/pset/rel")))
                    .null()
                    .null()
                    .null()
                    .ids(&partitions)
                    .id(pset);
            })?;
        }
        Ok(())
    }

    /// A placement in `frame` at height `z` (local frame), axes unrotated.
    fn level_placement(&mut self, frame: &ElementFrame, z: f64) -> Result<Id, ExportError> {
        let fp = frame.placement;
        self.placement(fp, DVec3::new(0.0, 0.0, z - frame.origin.z), DVec3::X)
    }

    /// A ring relative to the frame, as an `IfcArbitraryClosedProfileDef` (with voids when
    /// `holes` is not empty).
    fn plan_profile(
        &mut self,
        frame: &ElementFrame,
        outer: &[DVec2],
        holes: &[Vec<DVec2>],
    ) -> Result<Id, ExportError> {
        let shift = frame.origin.truncate();
        let rel = |r: &[DVec2]| r.iter().map(|p| *p - shift).collect::<Vec<_>>();
        let curve = self.closed_polyline2(&rel(outer))?;
        if holes.is_empty() {
            return Ok(self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
                a.enumeration("AREA").null().id(curve);
            })?);
        }
        let mut inner = Vec::with_capacity(holes.len());
        for h in holes {
            inner.push(self.closed_polyline2(&rel(h))?);
        }
        Ok(self.w.entity("IFCARBITRARYPROFILEDEFWITHVOIDS", |a| {
            a.enumeration("AREA").null().id(curve).ids(&inner);
        })?)
    }

    /// The `IfcSpace` of room `r`, with its base quantities; `None` for a degenerate room.
    fn space(
        &mut self,
        s: &StoreyInterior,
        r: usize,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let room = &s.rooms[r];
        let Some(ring) = lod4geom::room_ring(room) else {
            return Ok(None);
        };
        let height = s.ceiling_z - s.floor_z;
        if height.is_nan() || height <= EPS {
            return Ok(None);
        }
        let profile = self.plan_profile(frame, &ring, &[])?;
        let up = self.dir_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile).null().id(up).real(height);
        })?;
        let body_ctx = self.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        let space = self.w.entity("IFCSPACE", |a| {
            a.string(&global_id(key, path))
                .null()
                .string(&room.name)
                .null()
                .null()
                .id(pl)
                .id(shape)
                .string(&room.usage)
                .enumeration("ELEMENT")
                .enumeration("SPACE")
                .null();
        })?;
        let area = crate::geometry::ring_signed_area(&ring).abs();
        let perimeter: f64 = (0..ring.len())
            .map(|i| ring[i].distance(ring[(i + 1) % ring.len()]))
            .sum();
        let mut quantities = Vec::with_capacity(4);
        for (name, kind, value) in [
            ("NetFloorArea", "IFCQUANTITYAREA", area),
            ("GrossPerimeter", "IFCQUANTITYLENGTH", perimeter),
            ("Height", "IFCQUANTITYLENGTH", height),
            ("NetVolume", "IFCQUANTITYVOLUME", area * height),
        ] {
            quantities.push(self.w.entity(kind, |a| {
                a.string(name).null().null().real(value).null();
            })?);
        }
        let qto = self.w.entity("IFCELEMENTQUANTITY", |a| {
            a.string(&global_id(key, &format!("{path}/qto")))
                .null()
                .string("Qto_SpaceBaseQuantities")
                .null()
                .null()
                .ids(&quantities);
        })?;
        self.w.entity("IFCRELDEFINESBYPROPERTIES", |a| {
            a.string(&global_id(key, &format!("{path}/qto/rel")))
                .null()
                .null()
                .null()
                .ids(&[space])
                .id(qto);
        })?;
        Ok(Some(space))
    }

    /// Interior wall `wi` of `s` as an `IfcWallStandardCase`: returns the wall as the LOD3
    /// opening code sees it (its body's right face from `start` to `end`), its id and placement.
    fn partition(
        &mut self,
        s: &StoreyInterior,
        wi: usize,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<(Wall, Id, Id)>, ExportError> {
        let w = &s.walls[wi];
        let len = w.a.distance(w.b);
        let height = s.ceiling_z - s.floor_z;
        if !(len > EPS && w.thickness > EPS && height > EPS) {
            return Ok(None);
        }
        let dir = (w.b - w.a) / len;
        // The body spans +Y (left of a->b) from 0 to the thickness: start half of it right.
        let shift = -dir.perp() * (w.thickness / 2.0);
        let (start, end) = (w.a + shift, w.b + shift);
        let loc = start.extend(s.floor_z) - frame.origin;
        let placement = self.placement(frame.placement, loc, dir.extend(0.0))?;

        // The axis is the reference line of the shared layer set usage (offset 0, body on +Y),
        // as for the exterior walls.
        let (origin2, end2) = (self.origin2, self.point2(DVec2::new(len, 0.0))?);
        let axis_line = self.w.entity("IFCPOLYLINE", |a| {
            a.ids(&[origin2, end2]);
        })?;
        let axis_ctx = self.axis_ctx;
        let axis_rep = self.representation(axis_ctx, "Axis", "Curve2D", &[axis_line])?;
        let profile = self.rect_profile(0.0, 0.0, len, w.thickness)?;
        let up = self.dir_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile).null().id(up).real(height);
        })?;
        self.styled(solid, lod4geom::INTERIOR_WALL_COLOR)?;
        let body_ctx = self.body_ctx;
        let body_rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[axis_rep, body_rep])?;
        let name = format!("Interior wall {}.{wi}", s.storey);
        let id = self.w.entity("IFCWALLSTANDARDCASE", |a| {
            a.string(&global_id(key, path))
                .null()
                .string(&name)
                .null()
                .null()
                .id(placement)
                .id(shape)
                .null();
            a.enumeration("PARTITIONING");
        })?;
        let (f, c) = (s.floor_z, s.ceiling_z);
        let wall = Wall {
            start,
            end,
            base_z: f,
            top_z: c,
            thickness: w.thickness,
            outline: Face::new(vec![
                start.extend(f),
                end.extend(f),
                end.extend(c),
                start.extend(c),
            ]),
            storey: s.storey,
            openings: Vec::new(),
            balconies: Vec::new(),
        };
        Ok(Some((wall, id, placement)))
    }

    /// The stair of storey `s`: one extruded block per step; `None` when it has no step.
    fn stair(
        &mut self,
        s: &StoreyInterior,
        st: &crate::model::Stair,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let steps = lod4geom::stair_steps(s, st);
        if steps.is_empty() {
            return Ok(None);
        }
        let up = self.dir_z;
        let mut items = Vec::with_capacity(steps.len());
        for step in &steps {
            let profile = self.plan_profile(frame, &step.ring, &[])?;
            items.push(self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile).null().id(up).real(step.z1 - step.z0);
            })?);
        }
        for &item in &items {
            self.styled(item, lod4geom::STAIR_COLOR)?;
        }
        let body_ctx = self.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        Ok(Some(self.w.entity("IFCSTAIR", |a| {
            a.string(&global_id(key, path))
                .null()
                .string("Stair")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("STRAIGHT_RUN_STAIR");
        })?))
    }

    /// The floor slab of storey `s` above `below` ([`lod4geom::floor_slab`]); `None` for the
    /// ground storey or an empty slab.
    fn floor(
        &mut self,
        below: Option<&StoreyInterior>,
        s: &StoreyInterior,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let (pieces, thickness) = lod4geom::floor_slab(below, s);
        if pieces.is_empty() {
            return Ok(None);
        }
        let down = self.dir_neg_z;
        let mut items = Vec::with_capacity(pieces.len());
        for p in &pieces {
            let profile = self.plan_profile(frame, &p.outer, &p.holes)?;
            items.push(self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile).null().id(down).real(thickness);
            })?);
        }
        for &item in &items {
            self.styled(item, lod4geom::SLAB_COLOR)?;
        }
        let body_ctx = self.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        let name = format!("Floor {}", s.storey);
        Ok(Some(self.w.entity("IFCSLAB", |a| {
            a.string(&global_id(key, path))
                .null()
                .string(&name)
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("FLOOR");
        })?))
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::super::IfcWriter;
    use crate::crs::Crs;
    use crate::export::{fixtures, BuildingWriter, OutputContext};
    use crate::model::{Building, Lod};
    use glam::DVec3;

    fn ctx() -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: DVec3::new(574_000.0, 6_280_000.0, 150.0),
            origin_lonlat: (1.444, 43.6045),
            lod: Lod::Lod4,
            source_name: "lod4.osm.pbf".into(),
            seed: 7,
        }
    }

    fn write(buildings: &[Building]) -> Vec<u8> {
        let mut w = IfcWriter::new(Vec::new()).with_file_name("lod4.ifc");
        w.begin(&ctx()).unwrap();
        for b in buildings {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        w.into_inner().unwrap()
    }

    /// id -> (keyword, arguments split at top-level commas).
    fn parse(bytes: &[u8]) -> BTreeMap<u64, (String, Vec<String>)> {
        let text = std::str::from_utf8(bytes).unwrap();
        let data = text.split("DATA;\n").nth(1).unwrap();
        let mut out = BTreeMap::new();
        for line in data.lines().take_while(|l| *l != "ENDSEC;") {
            let (id, rest) = line.split_once('=').unwrap();
            let (kw, args) = rest.split_once('(').unwrap();
            let args = args.strip_suffix(");").unwrap();
            let (mut parts, mut cur, mut depth, mut in_str) = (Vec::new(), String::new(), 0, false);
            for c in args.chars() {
                match c {
                    '\'' => in_str = !in_str,
                    '(' if !in_str => depth += 1,
                    ')' if !in_str => depth -= 1,
                    ',' if !in_str && depth == 0 => {
                        parts.push(std::mem::take(&mut cur));
                        continue;
                    }
                    _ => {}
                }
                cur.push(c);
            }
            parts.push(cur);
            let id: u64 = id.trim_start_matches('#').parse().unwrap();
            out.insert(id, (kw.to_string(), parts));
        }
        out
    }

    /// The ids `#n` in an argument (a reference or a list of them).
    fn ids(arg: &str) -> Vec<u64> {
        arg.trim_matches(|c| c == '(' || c == ')')
            .split(',')
            .filter_map(|s| s.trim().strip_prefix('#'))
            .map(|s| s.parse().unwrap())
            .collect()
    }

    #[test]
    fn spaces_partitions_doors_stair_and_floor_per_storey() {
        let bs = fixtures::lod4_all();
        let m = parse(&write(&bs));
        let of = |kw: &str| -> Vec<u64> {
            m.iter()
                .filter(|(_, (k, _))| k == kw)
                .map(|(id, _)| *id)
                .collect()
        };
        let storey_name = |id: u64| m[&id].1[2].clone();
        // Spaces: aggregated under a storey, three per storey of the house.
        let spaces = of("IFCSPACE");
        assert_eq!(spaces.len(), 6);
        let mut per_storey: BTreeMap<String, usize> = BTreeMap::new();
        for s in &spaces {
            let rels: Vec<&(String, Vec<String>)> = m
                .values()
                .filter(|(k, a)| k == "IFCRELAGGREGATES" && ids(&a[5]).contains(s))
                .collect();
            assert_eq!(rels.len(), 1, "space #{s} aggregated once");
            let storey = ids(&rels[0].1[4])[0];
            assert_eq!(m[&storey].0, "IFCBUILDINGSTOREY");
            *per_storey.entry(storey_name(storey)).or_default() += 1;
            assert!(["'Hall'", "'Living room'", "'Bedroom 1'"].contains(&m[s].1[2].as_str()));
        }
        assert_eq!(per_storey.values().copied().collect::<Vec<_>>(), [3, 3]);
        assert_eq!(
            m.values()
                .filter(|(k, a)| k == "IFCELEMENTQUANTITY" && a[2] == "'Qto_SpaceBaseQuantities'")
                .count(),
            6
        );
        let area = m
            .values()
            .find(|(k, a)| k == "IFCQUANTITYAREA" && a[0] == "'NetFloorArea'")
            .map(|(_, a)| a[3].parse::<f64>().unwrap())
            .unwrap();
        assert!((area - 4.0 * 7.4).abs() < 1e-9, "hall area {area}");

        // Partitions: 3 per storey, contained in their storey.
        let partitions: Vec<u64> = of("IFCWALLSTANDARDCASE")
            .into_iter()
            .filter(|w| m[w].1[8] == ".PARTITIONING.")
            .collect();
        assert_eq!(partitions.len(), 6);
        let container = |e: u64| -> Vec<u64> {
            m.values()
                .filter(|(k, a)| {
                    k == "IFCRELCONTAINEDINSPATIALSTRUCTURE" && ids(&a[4]).contains(&e)
                })
                .map(|(_, a)| ids(&a[5])[0])
                .collect()
        };
        for w in &partitions {
            let c = container(*w);
            assert_eq!(c.len(), 1);
            assert_eq!(m[&c[0]].0, "IFCBUILDINGSTOREY");
        }
        // Interior doors: each in an opening voiding a partition, filled by a typed door.
        let mut interior_doors = 0;
        for (_, a) in m.values().filter(|(k, _)| k == "IFCRELVOIDSELEMENT") {
            let (wall, opening) = (ids(&a[4])[0], ids(&a[5])[0]);
            if !partitions.contains(&wall) {
                continue;
            }
            interior_doors += 1;
            let fills: Vec<u64> = m
                .values()
                .filter(|(k, f)| k == "IFCRELFILLSELEMENT" && ids(&f[4]) == [opening])
                .map(|(_, f)| ids(&f[5])[0])
                .collect();
            assert_eq!(fills.len(), 1);
            assert_eq!(m[&fills[0]].0, "IFCDOOR");
            assert_eq!(
                container(fills[0]),
                container(wall),
                "door in its wall's storey"
            );
            let typed = m.values().any(|(k, t)| {
                k == "IFCRELDEFINESBYTYPE"
                    && ids(&t[4]).contains(&fills[0])
                    && m[&ids(&t[5])[0]].0 == "IFCDOORTYPE"
            });
            assert!(typed);
        }
        assert_eq!(interior_doors, 4);
        // One stair (ground storey) with 17 steps; one upper floor slab with the well as a void.
        let stairs = of("IFCSTAIR");
        assert_eq!(stairs.len(), 1);
        assert_eq!(storey_name(container(stairs[0])[0]), "'Storey 0'");
        let floors: Vec<u64> = of("IFCSLAB")
            .into_iter()
            .filter(|s| m[s].1[2] == "'Floor 1'")
            .collect();
        assert_eq!(floors.len(), 1);
        assert_eq!(storey_name(container(floors[0])[0]), "'Storey 1'");
        // The courtyard sample's base slab, and the upper hall minus the stair well.
        assert_eq!(of("IFCARBITRARYPROFILEDEFWITHVOIDS").len(), 2);
    }

    #[test]
    fn lod4_output_is_deterministic() {
        let bs = fixtures::lod4_all();
        assert_eq!(write(&bs), write(&bs));
    }

    /// The reference validator with the geometry kernel, when installed: every space, wall,
    /// door, stair and slab builds. `CITYGEN_IFC_LOD4_SAMPLE=path` keeps the file.
    #[test]
    fn lod4_sample_passes_the_reference_validator() {
        let bytes = write(&fixtures::lod4_all());
        if let Some(keep) = std::env::var_os("CITYGEN_IFC_LOD4_SAMPLE") {
            std::fs::write(keep, &bytes).unwrap();
        }
        let Some(tool) = fixtures::validator() else {
            eprintln!("validate-outputs not installed: skipped");
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lod4.ifc");
        std::fs::write(&path, bytes).unwrap();
        let out = std::process::Command::new(tool)
            .arg("--geometry")
            .arg(&path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
        assert!(text.contains("Space=6"), "{text}");
        let shapes = text.split("shapes=").nth(1).unwrap_or("");
        let (ok, all) = shapes.split_once('/').unwrap();
        assert_eq!(ok, all.split_whitespace().next().unwrap(), "{text}");
    }
}
