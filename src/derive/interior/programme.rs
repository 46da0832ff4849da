//! Room programmes: which rooms a storey or a dwelling holds, with their legal minimum areas
//! and their weights for sharing out the surplus area (seed 001 §2.5: rooms start at the legal
//! minimum and the rest is water-filled by weight).

use crate::rng::Rng;

/// What a room is used for. Writers map it to IFC `LongName`/CityGML `function`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RoomKind {
    /// Entrance hall or landing of a dwelling; the reception of an office.
    Hall,
    /// A corridor serving several rooms or dwellings.
    Corridor,
    /// The stair core (the same rectangle on every storey).
    Stair,
    /// A living room (RGEU minimum 10 to 16 m² by typology); also a studio's one room.
    Living,
    /// A kitchen (RGEU minimum 6 m²).
    Kitchen,
    /// A bedroom, with its RGEU minimum by typology and rank.
    Bedroom,
    /// A bathroom or shower room (the RGEU sanitary space).
    Bathroom,
    /// A separate toilet.
    Wc,
    /// An office cell of the office programme.
    Office,
    /// An open-plan floor (office, workshop, garage, shed, church, ...).
    OpenPlan,
    /// The sales floor of a shop unit (retail programme).
    Shop,
    /// A shop's storage room (retail programme).
    Storage,
}

impl RoomKind {
    /// A human-readable English name ("Living room").
    pub fn label(self) -> &'static str {
        match self {
            RoomKind::Hall => "Hall",
            RoomKind::Corridor => "Corridor",
            RoomKind::Stair => "Stair",
            RoomKind::Living => "Living room",
            RoomKind::Kitchen => "Kitchen",
            RoomKind::Bedroom => "Bedroom",
            RoomKind::Bathroom => "Bathroom",
            RoomKind::Wc => "WC",
            RoomKind::Office => "Office",
            RoomKind::OpenPlan => "Open plan",
            RoomKind::Shop => "Shop",
            RoomKind::Storage => "Storage",
        }
    }

    /// How suitable the room is as a passage to another room: lower is better. Doors are
    /// grown from circulation first, so that a private room serves as a passage only when the
    /// geometry leaves no other way (seed 001, L91: "a private room never serves as a link").
    pub(crate) fn passage_rank(self) -> u32 {
        match self {
            RoomKind::Hall | RoomKind::Corridor => 0,
            RoomKind::Stair => 1,
            RoomKind::Living | RoomKind::OpenPlan | RoomKind::Shop => 2,
            RoomKind::Kitchen | RoomKind::Office | RoomKind::Storage => 3,
            RoomKind::Bedroom => 4,
            RoomKind::Bathroom | RoomKind::Wc => 5,
        }
    }
}

pub use crate::model::Programme;

/// One room to lay out: its kind, name, legal minimum area (when the programme is within the
/// storey area) and its target area.
#[derive(Clone, Debug)]
pub(crate) struct Item {
    pub kind: RoomKind,
    pub name: String,
    pub min_area: Option<f64>,
    pub area: f64,
    weight: f64,
    floor: f64,
}

impl Item {
    fn new(kind: RoomKind, name: impl Into<String>, min: Option<f64>, weight: f64) -> Item {
        Item {
            kind,
            name: name.into(),
            min_area: min,
            area: 0.0,
            weight,
            floor: 0.0,
        }
    }
}

/// RGEU Art. 67 minimum gross area of a dwelling T0..T5 (m²), seed 001 Appendix A.
pub const RGEU_GROSS: [f64; 6] = [35.0, 52.0, 72.0, 91.0, 105.0, 122.0];
/// RGEU Art. 66 bedroom minimums in order (double, then twins, then singles), seed 001
/// Appendix A.
const RGEU_BEDROOMS: [[f64; 5]; 6] = [
    [0.0; 5],
    [10.5, 0.0, 0.0, 0.0, 0.0],
    [10.5, 9.0, 0.0, 0.0, 0.0],
    [10.5, 9.0, 9.0, 0.0, 0.0],
    [10.5, 9.0, 9.0, 6.5, 0.0],
    [10.5, 9.0, 9.0, 9.0, 6.5],
];
/// RGEU Art. 66 living-room minimum per T0..T5.
const RGEU_LIVING: [f64; 6] = [10.0, 10.0, 12.0, 12.0, 12.0, 16.0];
/// RGEU Art. 66 kitchen minimum.
const RGEU_KITCHEN: f64 = 6.0;
/// A hall or landing: not an RGEU room (Art. 66 n.º 2); our own floor so it can hold a door.
const HALL_MIN: f64 = 2.5;

/// The dwelling typology T0..T5 for a usable dwelling area: the largest whose RGEU Art. 67
/// gross area fits, or `None` below T0.
pub fn typology(area: f64) -> Option<usize> {
    RGEU_GROSS.iter().rposition(|g| area >= *g)
}

/// The sanitary rooms of a Tx (RGEU Art. 68: T0-T2 one space ≥ 3.5 m²; T3-T4 4.5 m² in two
/// spaces; T5 6 m² in two). The split of the two-space totals is ours.
fn sanitary(t: usize) -> Vec<Item> {
    match t {
        0..=2 => vec![Item::new(RoomKind::Bathroom, "Bathroom", Some(3.5), 0.6)],
        3 | 4 => vec![
            Item::new(RoomKind::Bathroom, "Bathroom", Some(3.0), 0.5),
            Item::new(RoomKind::Wc, "WC", Some(1.5), 0.2),
        ],
        _ => vec![
            Item::new(RoomKind::Bathroom, "Bathroom 1", Some(3.5), 0.5),
            Item::new(RoomKind::Bathroom, "Bathroom 2", Some(2.5), 0.4),
        ],
    }
}

fn bedrooms(t: usize, first: usize, count: usize) -> Vec<Item> {
    (first..(first + count).min(t))
        .map(|i| {
            let min = RGEU_BEDROOMS[t.min(5)][i.min(4)];
            let w = if i == 0 { 2.0 } else { 1.6 };
            Item::new(
                RoomKind::Bedroom,
                format!("Bedroom {}", i + 1),
                Some(min),
                w,
            )
        })
        .collect()
}

/// Water-fills the area: every item gets its minimum (or a small floor when it has none), the
/// surplus is shared by weight (jittered ±15 % by the generator). When the minimums do not fit,
/// the minimums are dropped (the programme is beyond the area) and areas go by weight.
pub(crate) fn distribute(items: &mut [Item], area: f64, rng: &mut Rng) {
    for it in items.iter_mut() {
        it.weight *= rng.range(0.85, 1.15);
        it.floor = it.min_area.unwrap_or(match it.kind {
            RoomKind::Hall => HALL_MIN,
            RoomKind::Wc => 1.2,
            RoomKind::Bathroom => 2.5,
            _ => 0.0,
        });
    }
    let floors: f64 = items.iter().map(|i| i.floor).sum();
    let weights: f64 = items.iter().map(|i| i.weight).sum::<f64>().max(1e-9);
    if floors > area {
        for it in items.iter_mut() {
            it.min_area = None;
            it.area = area * it.weight / weights;
        }
        return;
    }
    let surplus = area - floors;
    for it in items.iter_mut() {
        it.area = it.floor + surplus * it.weight / weights;
    }
}

/// Which storey of a dwelling a programme is for.
#[derive(Clone, Copy, Debug)]
pub(crate) enum DwellingPart {
    /// A whole dwelling on one storey (flat or single-storey house).
    Whole,
    /// The ground floor of a house: hall, living room, kitchen and the second sanitary room.
    Ground,
    /// An upper floor of a house: a landing, bedrooms `first..first+count`, a bathroom.
    Upper { first: usize, count: usize },
}

/// The rooms of (a storey of) a dwelling of typology `t` (`None`: a studio below T0).
pub(crate) fn dwelling(t: Option<usize>, part: DwellingPart, unit: &str) -> Vec<Item> {
    let name = |s: &str| {
        if unit.is_empty() {
            s.to_string()
        } else {
            format!("{unit} {s}")
        }
    };
    let mut items = Vec::new();
    let Some(t) = t else {
        items.push(Item::new(RoomKind::Living, name("Studio"), None, 4.0));
        items.push(Item::new(RoomKind::Bathroom, name("Bathroom"), None, 0.6));
        return items;
    };
    let rename = |mut v: Vec<Item>| {
        for it in &mut v {
            it.name = name(&it.name);
        }
        v
    };
    match part {
        DwellingPart::Whole => {
            // Public rooms first: the layout puts the first items at the front.
            items.push(Item::new(RoomKind::Hall, "Hall", None, 0.5));
            items.push(Item::new(
                RoomKind::Living,
                "Living room",
                Some(RGEU_LIVING[t]),
                3.0,
            ));
            items.push(Item::new(
                RoomKind::Kitchen,
                "Kitchen",
                Some(RGEU_KITCHEN),
                1.4,
            ));
            items.extend(sanitary(t));
            items.extend(bedrooms(t, 0, t));
        }
        DwellingPart::Ground => {
            items.push(Item::new(RoomKind::Hall, "Hall", None, 0.6));
            items.push(Item::new(
                RoomKind::Living,
                "Living room",
                Some(RGEU_LIVING[t]),
                3.0,
            ));
            items.push(Item::new(
                RoomKind::Kitchen,
                "Kitchen",
                Some(RGEU_KITCHEN),
                1.4,
            ));
            // The second sanitary space (WC) goes downstairs; a T0-T2 house gets a WC without
            // a legal minimum.
            let san = sanitary(t);
            if san.len() == 2 {
                items.push(san[1].clone());
            } else {
                items.push(Item::new(RoomKind::Wc, "WC", None, 0.2));
            }
        }
        DwellingPart::Upper { first, count } => {
            items.push(Item::new(RoomKind::Hall, "Landing", None, 0.4));
            items.extend(bedrooms(t, first, count));
            let mut bath = sanitary(t).remove(0);
            if first > 0 {
                // The main bathroom's legal minimum applies once, on the first upper floor.
                bath.min_area = None;
                bath.name = "Shower room".into();
            }
            items.push(bath);
        }
    }
    rename(items)
}

/// An item without a legal minimum.
pub(crate) fn item(kind: RoomKind, name: String, weight: f64) -> Item {
    Item::new(kind, name, None, weight)
}
