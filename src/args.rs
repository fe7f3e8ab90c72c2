//! Parsers for the values the command-line program and the example binaries share, so that
//! `--size` and `--eye` mean the same, with the same messages, everywhere.

use glam::Vec3;
use sightline_render::Antialias;

/// `WIDTHxHEIGHT` (or `WIDTHXHEIGHT`), each side 1 to 8192: an image or window size.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}': expected WIDTHxHEIGHT, each 1 to 8192, e.g. 1280x720");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (w.trim().parse::<u32>().map_err(|_| bad())?, h.trim().parse::<u32>().map_err(|_| bad())?);
    if w == 0 || h == 0 || w > 8192 || h > 8192 {
        return Err(bad());
    }
    Ok((w, h))
}

/// `x,y,z`: three finite numbers.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}': expected x,y,z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(format!("'{s}': expected three finite numbers x,y,z")),
    }
}

/// `--aa` (alias `--supersample`): samples per pixel side of a picture, `off` (or `1`), `2x2`
/// (or `2`), `4x4` (or `4`).
pub fn parse_aa(s: &str) -> Result<Antialias, String> {
    match s.trim() {
        "off" | "1" => Ok(Antialias::Off),
        "2x2" | "2" => Ok(Antialias::Ssaa2x2),
        "4x4" | "4" => Ok(Antialias::Ssaa4x4),
        _ => Err(format!("'{s}': expected off, 2x2 or 4x4 (or 1, 2, 4 samples per pixel side)")),
    }
}

/// Parses a time in seconds (`--time`): a finite number, not negative.
pub fn parse_time(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{s}' is not a time in seconds (a finite number ≥ 0)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_vectors_parse_and_bad_ones_are_named() {
        assert_eq!(parse_size("1280x720"), Ok((1280, 720)));
        assert_eq!(parse_size(" 64 X 36 "), Ok((64, 36)));
        for bad in ["0x10", "8193x1", "12", "ax3"] {
            assert!(parse_size(bad).unwrap_err().contains(bad), "{bad}");
        }
        assert_eq!(parse_vec3("1, -2,3.5"), Ok(Vec3::new(1.0, -2.0, 3.5)));
        assert_eq!(parse_aa("2"), Ok(Antialias::Ssaa2x2));
        assert_eq!(parse_aa("4x4"), Ok(Antialias::Ssaa4x4));
        assert_eq!(parse_aa("off"), parse_aa("1"));
        assert!(parse_aa("3x3").unwrap_err().contains("3x3"));
        assert!(parse_vec3("1,2").is_err() && parse_vec3("1,2,nan").is_err() && parse_vec3("a,b,c").is_err());
    }
}
