//! Scripted input for `rtsl view --events`: a list of input events that the window plays through
//! its ordinary input handlers, one step per displayed frame, so tests drive the viewer
//! deterministically without an X11 input injector.
//!
//! Syntax: steps separated by `;`, each `NAME:ARGS` with comma-separated numbers:
//! `drag:X0,Y0,X1,Y1` (left button: orbit), `rdrag:X0,Y0,X1,Y1` (right button: look),
//! `shiftdrag:X0,Y0,X1,Y1` (shift + left: select and move the object under X0,Y0),
//! `click:X,Y` (select), `move:X,Y` (the cursor moves there, no button held), `scroll:STEPS` (positive: towards the pivot), `key:NAME` (press and
//! release a key: a letter, a digit, `tab`, `space`, `escape`, `f1`), `hold:KEY,SECONDS` (a flying
//! key held for that long, as if at the fly speed), `wait:FRAMES`.

/// One step of a script.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    Drag { button: DragButton, from: (f32, f32), to: (f32, f32) },
    Click { at: (f32, f32) },
    Move { to: (f32, f32) },
    Scroll { steps: f32 },
    Key { name: String },
    Hold { key: char, seconds: f32 },
    Wait { frames: u32 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DragButton {
    Left,
    Right,
    ShiftLeft,
}

/// Keys a script may name besides single letters and digits.
pub const NAMED_KEYS: [&str; 5] = ["tab", "space", "escape", "f1", "shift"];

fn numbers(step: &str, args: &str, count: usize) -> Result<Vec<f32>, String> {
    let v: Vec<f32> = args
        .split(',')
        .map(|a| a.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{step}`: expected {count} numbers separated by commas"))?;
    if v.len() != count {
        return Err(format!("`{step}`: expected {count} numbers, found {}", v.len()));
    }
    Ok(v)
}

/// Parses a script; an error names the step at fault.
pub fn parse(script: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for raw in script.split(';').map(str::trim).filter(|s| !s.is_empty()) {
        let (name, args) = raw.split_once(':').ok_or_else(|| format!("`{raw}`: expected NAME:ARGS"))?;
        let step = match name.trim() {
            "drag" | "rdrag" | "shiftdrag" => {
                let v = numbers(raw, args, 4)?;
                let button = match name.trim() {
                    "drag" => DragButton::Left,
                    "rdrag" => DragButton::Right,
                    _ => DragButton::ShiftLeft,
                };
                Step::Drag { button, from: (v[0], v[1]), to: (v[2], v[3]) }
            }
            "click" => {
                let v = numbers(raw, args, 2)?;
                Step::Click { at: (v[0], v[1]) }
            }
            "move" => {
                let v = numbers(raw, args, 2)?;
                Step::Move { to: (v[0], v[1]) }
            }
            "scroll" => Step::Scroll { steps: numbers(raw, args, 1)?[0] },
            "key" => {
                let key = args.trim().to_ascii_lowercase();
                let single = key.chars().count() == 1 && key.chars().all(|c| c.is_ascii_alphanumeric());
                if !single && !NAMED_KEYS.contains(&key.as_str()) {
                    return Err(format!("`{raw}`: unknown key (a letter, a digit, or {})", NAMED_KEYS.join(", ")));
                }
                Step::Key { name: key }
            }
            "hold" => {
                let (key, secs) = args.split_once(',').ok_or_else(|| format!("`{raw}`: expected KEY,SECONDS"))?;
                let key = key.trim().to_ascii_lowercase();
                let mut chars = key.chars();
                let (Some(c), None) = (chars.next(), chars.next()) else {
                    return Err(format!("`{raw}`: the key is one of w a s d q e"));
                };
                if !"wasdqe".contains(c) {
                    return Err(format!("`{raw}`: the key is one of w a s d q e"));
                }
                let seconds = numbers(raw, secs, 1)?[0];
                if !(0.0..=60.0).contains(&seconds) {
                    return Err(format!("`{raw}`: seconds out of range (0 to 60)"));
                }
                Step::Hold { key: c, seconds }
            }
            "wait" => {
                let frames = args.trim().parse::<u32>().map_err(|_| format!("`{raw}`: expected a frame count"))?;
                Step::Wait { frames }
            }
            other => {
                return Err(format!(
                    "`{raw}`: unknown step `{other}` (drag, rdrag, shiftdrag, click, move, scroll, key, hold, wait)"
                ))
            }
        };
        steps.push(step);
    }
    Ok(steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_step() {
        let s = parse(
            "drag:10,20,30,40; rdrag:1,2,3,4;shiftdrag:5,5,6,6;click:7,8;scroll:-2;key:A;key:tab;hold:w,0.5;wait:3",
        )
        .expect("a valid script");
        assert_eq!(s.len(), 9);
        assert_eq!(s[0], Step::Drag { button: DragButton::Left, from: (10.0, 20.0), to: (30.0, 40.0) });
        assert_eq!(s[2], Step::Drag { button: DragButton::ShiftLeft, from: (5.0, 5.0), to: (6.0, 6.0) });
        assert_eq!(s[4], Step::Scroll { steps: -2.0 });
        assert_eq!(s[5], Step::Key { name: "a".into() });
        assert_eq!(s[7], Step::Hold { key: 'w', seconds: 0.5 });
        assert_eq!(s[8], Step::Wait { frames: 3 });
    }

    #[test]
    fn errors_name_the_step() {
        for (bad, what) in [
            ("drag:1,2,3", "drag:1,2,3"),
            ("jump:1", "unknown step"),
            ("key:ctrl", "unknown key"),
            ("hold:x,1", "w a s d q e"),
            ("click:a,b", "click:a,b"),
            ("wait", "NAME:ARGS"),
            ("scroll:nan", "scroll:nan"),
        ] {
            let e = parse(bad).expect_err(bad);
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
