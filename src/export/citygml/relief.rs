//! The terrain of a file as a CityGML 2.0 relief feature: one `core:cityObjectMember` holding a
//! `dem:ReliefFeature` (its `dem:lod` the run's) with one `dem:TINRelief` component whose
//! `dem:tin` is a `gml:TriangulatedSurface`, a `gml:Triangle` per triangle (counter-clockwise
//! seen from above, so its normal points up), coordinates `origin + local point` to the
//! millimetre as the buildings'.

use std::io::{self, Write};

use glam::DVec3;

use super::xml::Xml;
use crate::model::Terrain;

/// Triangles rendered into the buffer before it goes to the output.
const FLUSH_EVERY: usize = 4096;

/// Writes the relief feature of `t` with gml:id `id` (its component `id_tin`) to `out`,
/// through the scratch buffer `x`.
pub(super) fn relief(
    x: &mut Xml,
    out: &mut impl Write,
    t: &Terrain,
    id: &str,
    (origin, srs, lod): (DVec3, &str, &str),
) -> io::Result<()> {
    x.0.clear();
    x.s("<core:cityObjectMember>\n<dem:ReliefFeature gml:id=\"");
    x.s(id);
    x.s("\">\n<gml:name>terrain</gml:name>\n<dem:lod>");
    x.s(lod);
    x.s("</dem:lod>\n<dem:reliefComponent>\n<dem:TINRelief gml:id=\"");
    x.s(id);
    x.s("_tin\">\n<dem:lod>");
    x.s(lod);
    x.s("</dem:lod>\n<dem:tin>\n<gml:TriangulatedSurface srsName=\"");
    x.s(srs);
    x.s("\" srsDimension=\"3\">\n<gml:trianglePatches>\n");
    for (n, tri) in t.triangles.iter().enumerate() {
        if n % FLUSH_EVERY == FLUSH_EVERY - 1 {
            out.write_all(&x.0)?;
            x.0.clear();
        }
        x.s("<gml:Triangle><gml:exterior><gml:LinearRing><gml:posList>");
        for (i, &k) in tri.iter().chain(tri.first()).enumerate() {
            if i > 0 {
                x.s(" ");
            }
            x.point(origin + t.vertices.get(k as usize).copied().unwrap_or_default());
        }
        x.s("</gml:posList></gml:LinearRing></gml:exterior></gml:Triangle>\n");
    }
    x.s("</gml:trianglePatches>\n</gml:TriangulatedSurface>\n</dem:tin>\n</dem:TINRelief>\n");
    x.s("</dem:reliefComponent>\n</dem:ReliefFeature>\n</core:cityObjectMember>\n");
    out.write_all(&x.0)
}
