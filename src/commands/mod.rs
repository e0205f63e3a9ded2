//! The CLI subcommands' logic (the binary in `main.rs` only parses arguments and reports
//! errors).

pub mod eval;
pub mod render;
pub mod ssim;
pub mod throughput;
pub mod tradeoff;

use crate::kernels::Extent;

/// Parses `WxH` into a validated extent.
pub fn parse_resolution(s: &str) -> Result<Extent, String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("resolution '{s}' is not of the form WIDTHxHEIGHT"))?;
    let parse = |v: &str, what: &str| {
        v.trim().parse::<usize>().map_err(|_| format!("resolution '{s}': {what} '{v}' is not a whole number"))
    };
    let (w, h) = (parse(w, "width")?, parse(h, "height")?);
    Extent::new(w, h).map_err(|e| format!("resolution '{s}': {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolutions_parse_and_bad_ones_are_explained() {
        assert_eq!(parse_resolution("1280x720").unwrap(), Extent::new(1280, 720).unwrap());
        assert!(parse_resolution("1280").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_resolution("0x10").unwrap_err().contains("zero"));
        assert!(parse_resolution("axb").unwrap_err().contains("whole number"));
        assert!(parse_resolution("100000x10").unwrap_err().contains("too large"));
    }
}
