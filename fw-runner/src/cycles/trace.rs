//! The plugin's output file: one line per priced window, one for the dropped ones, and a
//! `group` line where the firmware started another group of windows (`fw-bench`'s next
//! drive).

use super::tracker::{Which, Window};

/// One window as a line of the plugin's output file.
#[must_use]
pub fn window_line(which: Which, w: &Window) -> String {
    let tag = match which {
        Which::Current => "current",
        Which::Velocity => "velocity",
    };
    format!(
        "{tag} {} {} {} {} {} {}",
        w.instructions, w.cycles, w.taken, w.divides, w.fpu, w.unknown
    )
}

/// What the plugin's output file holds.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Trace {
    /// The windows, in order.
    pub windows: Vec<(Which, Window)>,
    /// Windows dropped because an interrupt came into them.
    pub dropped: u32,
}

impl Trace {
    /// Parses the plugin's output file.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut t = Self::default();
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            let mut f = line.split_whitespace();
            let tag = f.next().unwrap_or_default();
            let nums: Vec<u32> = f
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|e| format!("cycle trace: bad line {line:?}: {e}"))?;
            let which = match tag {
                "current" => Which::Current,
                "velocity" => Which::Velocity,
                "dropped" => {
                    t.dropped += nums.first().copied().unwrap_or(0);
                    continue;
                }
                _ => return Err(format!("cycle trace: unknown line {line:?}")),
            };
            let [instructions, cycles, taken, divides, fpu, unknown] = nums[..] else {
                return Err(format!("cycle trace: line {line:?} needs 6 numbers"));
            };
            t.windows.push((
                which,
                Window {
                    instructions,
                    cycles,
                    taken,
                    divides,
                    fpu,
                    unknown,
                },
            ));
        }
        Ok(t)
    }

    /// Parses the plugin's output file into its groups (split at its `group` lines), in
    /// order; a file without one is one group.
    pub fn parse_groups(text: &str) -> Result<Vec<Self>, String> {
        let mut groups = vec![String::new()];
        for line in text.lines() {
            if line.trim() == "group" {
                groups.push(String::new());
            } else if let Some(g) = groups.last_mut() {
                g.push_str(line);
                g.push('\n');
            }
        }
        groups.iter().map(|g| Self::parse(g)).collect()
    }

    /// The windows of one kind.
    pub fn of(&self, which: Which) -> impl Iterator<Item = &Window> {
        self.windows
            .iter()
            .filter(move |(w, _)| *w == which)
            .map(|(_, w)| w)
    }
}
