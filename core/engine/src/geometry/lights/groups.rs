//! Light groups: which group each light and the world fall in under a [`LightGrouping`],
//! and the colour a group's emitters share ([`common_tint`]), factored out of them so that
//! the bake can use grey light.

use crate::options::LightGrouping;
use crate::scene::{Light, Scene, World};
use crate::Rgb;

/// The colour shared by a set of emitter colours, if there is one: when all are
/// proportional to one colour c, the bake can use grey light and the relight multiply by c,
/// so paths that meet no other colour stay grey layers (one channel instead of three: a
/// third of the memory and of the relight's reads). Returns c scaled to a largest component
/// of 1, or white when the colours differ or `image_world` (an environment image is never
/// one colour). Proportional means equal after scaling within 1e-6 relative.
pub fn common_tint(colours: &[Rgb], image_world: bool) -> Rgb {
    if image_world {
        return Rgb::ONE;
    }
    let normalised: Vec<Rgb> = colours
        .iter()
        .filter(|c| c.max_element() > 0.0)
        .map(|c| *c / c.max_element())
        .collect();
    let Some(first) = normalised.first() else {
        return Rgb::ONE;
    };
    if normalised
        .iter()
        .all(|c| (*c - *first).abs().max_element() <= 1e-6)
    {
        *first
    } else {
        Rgb::ONE
    }
}

/// The emitted colour of a light (zero when it emits nothing).
pub(super) fn light_colour(light: &Light) -> Rgb {
    match light {
        Light::Point { color, power, .. }
        | Light::Spot { color, power, .. }
        | Light::Area { color, power, .. } => Rgb::from(*color) * power.signum().max(0.0),
        Light::Sun {
            color, strength, ..
        }
        | Light::Emissive {
            color, strength, ..
        } => Rgb::from(*color) * strength.signum().max(0.0),
    }
}

/// A set of emitters whose layers are kept apart (a light group), and its common colour.
#[derive(Clone, Debug, PartialEq)]
pub struct LightGroup {
    pub name: String,
    pub tint: Rgb,
}

/// The name of the group holding the lights (and the world) that no scene light group lists.
pub const DEFAULT_LIGHT_GROUP: &str = "default";

/// Which group each light and the world fall in, with the groups' names.
pub(super) fn group_membership(
    scene: &Scene,
    grouping: LightGrouping,
) -> (Vec<String>, Vec<usize>, usize) {
    match grouping {
        LightGrouping::All => (vec!["all".into()], vec![0; scene.lights.len()], 0),
        LightGrouping::PerLight => {
            let mut names: Vec<String> = (0..scene.lights.len())
                .map(|i| format!("light {i}"))
                .collect();
            let world_emits = match &scene.world {
                World::Color { color, strength } => {
                    *strength > 0.0 && color.iter().any(|c| *c > 0.0)
                }
                World::Equirect { strength, .. } => *strength > 0.0,
            };
            // The world gets a group of its own only when it emits.
            // (and when there is no light at all, so that there is always one group).
            let world = if world_emits || names.is_empty() {
                names.push("world".into());
                scene.lights.len()
            } else {
                0
            };
            (names, (0..scene.lights.len()).collect(), world)
        }
        LightGrouping::Scene => {
            let mut names: Vec<String> =
                scene.light_groups.iter().map(|g| g.name.clone()).collect();
            // A group the scene itself names "default" is that group (as the add-on maps
            // Blender's group of that name): a second one would make edits by name ambiguous.
            let default = match names.iter().position(|n| n == DEFAULT_LIGHT_GROUP) {
                Some(g) => g,
                None => {
                    names.push(DEFAULT_LIGHT_GROUP.into());
                    names.len() - 1
                }
            };
            let mut member = vec![default; scene.lights.len()];
            let mut world = default;
            for (g, spec) in scene.light_groups.iter().enumerate() {
                for &l in &spec.lights {
                    if let Some(m) = member.get_mut(l as usize) {
                        *m = g;
                    }
                }
                if spec.world {
                    world = g;
                }
            }
            (names, member, world)
        }
    }
}

/// `colour` with the tint factored out: a grey of the same largest component when the tint
/// is not white (so the bake's grey layers are bit-exact), the colour itself otherwise.
pub(super) fn untinted(colour: Rgb, tint: Rgb) -> Rgb {
    if tint == Rgb::ONE {
        colour
    } else {
        Rgb::splat(colour.max_element())
    }
}
