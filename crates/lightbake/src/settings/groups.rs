//! Light groups: which lights, emissive materials and sky bake into a set of lightmaps of
//! their own. Light adds up, so a game shows any weighted sum of the groups' lightmaps
//! (day and night, a lamp switched off) without a rebake.
//!
//! | field | meaning | default |
//! |---|---|---|
//! | `groups` | the named groups, each with its members | none: one set of lightmaps |
//!
//! A member is a light's name (every light of that name), an emissive material's name, or
//! [`SKY`]; `light:NAME` and `material:NAME` say which when a light and a material share a
//! name. Every light, emissive material and the sky belongs to at most one group; those no
//! group names bake into the group [`UNGROUPED`] (written only when it has something to
//! bake). The scene's members are resolved against the scene when the bake starts
//! (`lightbake::scene::groups`), and a member that names nothing is refused there.

use serde::{Deserialize, Serialize};

use crate::error::{BakeError, Result};

/// The member that names the scene's uniform sky.
pub const SKY: &str = "sky";

/// The group of the emitters that no group names.
pub const UNGROUPED: &str = "ungrouped";

/// The most named groups a bake takes: with [`UNGROUPED`], 16 sets of pages, which the Bevy
/// plugin sums in one pass of 16 textures (the least every GPU binds). Each group costs a
/// set of lighting passes and of pages.
pub const MAX_GROUPS: usize = 15;

/// The longest group name, characters.
pub const MAX_NAME: usize = 64;

/// One light group: a name (it names the group's folder of lightmaps, so letters, digits,
/// `_` and `-` only) and its members.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LightGroup {
    /// The group's name: 1–64 of `A–Z a–z 0–9 _ -`; not [`UNGROUPED`].
    pub name: String,
    /// Light names, emissive material names, `light:NAME`, `material:NAME` or [`SKY`].
    pub members: Vec<String>,
}

impl LightGroup {
    /// Parses the CLI's `NAME=member,member` (members trimmed, empty ones dropped).
    ///
    /// # Errors
    /// [`BakeError::BadSetting`] for a text without `=`; the name and members are checked by
    /// [`check`].
    pub fn parse(text: &str) -> Result<Self> {
        let Some((name, members)) = text.split_once('=') else {
            return Err(BakeError::BadSetting {
                name: "group",
                value: text.to_string(),
                message: "write a light group as NAME=light,light (members are light names, emissive material names or 'sky')".into(),
            });
        };
        Ok(Self {
            name: name.trim().to_string(),
            members: (members.split(','))
                .map(str::trim)
                .filter(|m| !m.is_empty())
                .map(str::to_string)
                .collect(),
        })
    }
}

/// Checks the groups' names and member lists (not what the members name: that needs the
/// scene).
///
/// # Errors
/// [`BakeError::BadSetting`] naming the group: a name that is empty, too long, has a
/// character other than letters, digits, `_` and `-`, is [`UNGROUPED`] or repeats; a group
/// with no members; more than [`MAX_GROUPS`] groups.
pub fn check(groups: &[LightGroup]) -> Result<()> {
    let bad = |value: &str, message: String| BakeError::BadSetting {
        name: "groups",
        value: value.to_string(),
        message,
    };
    if groups.len() > MAX_GROUPS {
        return Err(bad(
            &groups.len().to_string(),
            format!("at most {MAX_GROUPS} light groups"),
        ));
    }
    for (i, g) in groups.iter().enumerate() {
        let name = &g.name;
        let ok_chars = name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        if name.is_empty() || name.len() > MAX_NAME || !ok_chars {
            return Err(bad(
                name,
                format!(
                    "a light group's name names its lightmaps' folder: 1 to {MAX_NAME} letters, digits, '_' or '-'"
                ),
            ));
        }
        if name == UNGROUPED {
            return Err(bad(
                name,
                format!(
                    "'{UNGROUPED}' is the group of the lights no group names; pick another name"
                ),
            ));
        }
        if groups[..i].iter().any(|o| o.name == *name) {
            return Err(bad(name, "two light groups have this name".into()));
        }
        if g.members.is_empty() {
            return Err(bad(
                name,
                "the light group names no light, emissive material or sky".into(),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_checks() {
        let g = LightGroup::parse("night= lamp, material:Neon ,,sky").unwrap();
        assert_eq!(g.name, "night");
        assert_eq!(g.members, ["lamp", "material:Neon", "sky"]);
        assert!(LightGroup::parse("night").is_err());
        check(std::slice::from_ref(&g)).unwrap();
        let named = |n: &str| LightGroup {
            name: n.into(),
            ..g.clone()
        };
        for bad in ["", "a b", "a/b", "..", UNGROUPED] {
            assert!(check(&[named(bad)]).is_err(), "{bad:?}");
        }
        assert!(check(&[named("a"), named("a")]).is_err());
        let empty = LightGroup::parse("day=").unwrap();
        let e = check(&[empty]).unwrap_err().to_string();
        assert!(e.contains("day") && e.contains("names no light"), "{e}");
    }
}
