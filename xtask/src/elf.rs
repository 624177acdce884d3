//! Minimal ELF32 little-endian section-header reader: flash and static-RAM use of
//! a Cortex-M image, without depending on binutils being installed. The one
//! ELF-size implementation of the repository: `cargo xtask size [ELF]
//! [--flash-max BYTES] [--ram-max BYTES]` (the release firmware when no ELF is
//! given; exit 1 over a limit).

/// Bytes a firmware image occupies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sizes {
    /// Flash: every allocated section that is not .bss-like (vector table, text, rodata, .data's initialiser).
    pub flash: u64,
    /// Initialised RAM (.data), bytes (also counted in flash).
    pub data: u64,
    /// Zero-initialised and uninitialised RAM (.bss, .uninit), bytes.
    pub bss: u64,
}

impl Sizes {
    /// Static RAM: .data + .bss.
    pub fn ram(&self) -> u64 {
        self.data + self.bss
    }
}

const SHF_ALLOC: u32 = 0x2;
const SHF_WRITE: u32 = 0x1;
const SHT_NOBITS: u32 = 8;

fn u16le(b: &[u8], o: usize) -> Result<u16, String> {
    b.get(o..o + 2).map(|s| u16::from_le_bytes([s[0], s[1]])).ok_or_else(|| "truncated ELF".to_string())
}
fn u32le(b: &[u8], o: usize) -> Result<u32, String> {
    b.get(o..o + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| "truncated ELF".to_string())
}

/// Sum the allocated sections of an ELF32 image.
pub fn sizes(b: &[u8]) -> Result<Sizes, String> {
    if b.len() < 52 || &b[..4] != b"\x7fELF" {
        return Err("not an ELF file".into());
    }
    if b[4] != 1 || b[5] != 1 {
        return Err("not a 32-bit little-endian ELF".into());
    }
    let shoff = u32le(b, 32)? as usize;
    let shentsize = u16le(b, 46)? as usize;
    let shnum = u16le(b, 48)? as usize;
    let mut s = Sizes { flash: 0, data: 0, bss: 0 };
    for i in 0..shnum {
        let h = shoff + i * shentsize;
        let sh_type = u32le(b, h + 4)?;
        let flags = u32le(b, h + 8)?;
        let size = u64::from(u32le(b, h + 20)?);
        if flags & SHF_ALLOC == 0 {
            continue;
        }
        if sh_type == SHT_NOBITS {
            s.bss += size;
        } else if flags & SHF_WRITE != 0 {
            s.data += size;
            s.flash += size;
        } else {
            s.flash += size;
        }
    }
    Ok(s)
}

/// `cargo xtask size` options.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SizeArgs {
    /// The ELF to measure; `None`: build and measure the release firmware.
    pub elf: Option<std::path::PathBuf>,
    /// Flash limit, bytes.
    pub flash_max: Option<u64>,
    /// Static-RAM limit (.data + .bss), bytes.
    pub ram_max: Option<u64>,
    /// `--by-source`: also print the code bytes per source area (`by_source.rs`).
    pub by_source: bool,
    /// `--features LIST`: cargo features added to the F405 build (e.g. `onboard-log`); only
    /// without `ELF`.
    pub features: Option<String>,
}

/// Parse `[ELF] [--flash-max BYTES] [--ram-max BYTES] [--by-source] [--features LIST]`.
pub fn parse_args(args: &[String]) -> Result<SizeArgs, String> {
    let mut a = SizeArgs::default();
    let mut it = args.iter();
    while let Some(x) = it.next() {
        let mut limit = |name: &str| -> Result<u64, String> {
            let v = it.next().ok_or_else(|| format!("{name} needs a value (bytes)"))?;
            v.parse().map_err(|_| format!("{name}: not a byte count: {v:?}"))
        };
        match x.as_str() {
            "--flash-max" => a.flash_max = Some(limit("--flash-max")?),
            "--ram-max" => a.ram_max = Some(limit("--ram-max")?),
            "--by-source" => a.by_source = true,
            "--features" => {
                let v = it.next().ok_or("--features needs a value (cargo features, e.g. onboard-log)")?;
                a.features = Some(v.clone());
            }
            s if s.starts_with("--") => return Err(format!("unknown option {s}")),
            s if a.elf.is_none() => a.elf = Some(s.into()),
            s => return Err(format!("more than one ELF given ({s})")),
        }
    }
    if a.elf.is_some() && a.features.is_some() {
        return Err("--features builds the image: give it without an ELF".into());
    }
    Ok(a)
}

/// The limits `s` exceeds, in words (empty: within every limit).
pub fn over_limits(s: &Sizes, a: &SizeArgs) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(m) = a.flash_max.filter(|m| s.flash > *m) {
        out.push(format!("flash {} B > {m} B", s.flash));
    }
    if let Some(m) = a.ram_max.filter(|m| s.ram() > *m) {
        out.push(format!("static RAM {} B > {m} B", s.ram()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_non_elf() {
        assert!(sizes(b"not an elf file at all, just some bytes here to be long enough....").is_err());
    }

    #[test]
    fn reads_own_section_table_shape() {
        // A hand-built ELF32 with three sections: .text (alloc), .data (alloc+write), .bss (nobits).
        let mut b = vec![0u8; 52 + 4 * 40];
        b[..4].copy_from_slice(b"\x7fELF");
        b[4] = 1;
        b[5] = 1;
        b[32..36].copy_from_slice(&52u32.to_le_bytes());
        b[46..48].copy_from_slice(&40u16.to_le_bytes());
        b[48..50].copy_from_slice(&4u16.to_le_bytes());
        let mut sec = |i: usize, ty: u32, flags: u32, size: u32| {
            let h = 52 + i * 40;
            b[h + 4..h + 8].copy_from_slice(&ty.to_le_bytes());
            b[h + 8..h + 12].copy_from_slice(&flags.to_le_bytes());
            b[h + 20..h + 24].copy_from_slice(&size.to_le_bytes());
        };
        sec(1, 1, SHF_ALLOC, 1000);
        sec(2, 1, SHF_ALLOC | SHF_WRITE, 100);
        sec(3, SHT_NOBITS, SHF_ALLOC | SHF_WRITE, 400);
        assert_eq!(sizes(&b), Ok(Sizes { flash: 1100, data: 100, bss: 400 }));
    }

    #[test]
    fn size_options_and_limits() {
        let args = |v: &[&str]| parse_args(&v.iter().map(|s| s.to_string()).collect::<Vec<_>>());
        let a = args(&["fw.elf", "--flash-max", "1000", "--ram-max", "600"]).unwrap();
        assert_eq!(a.elf.as_deref(), Some(std::path::Path::new("fw.elf")));
        let s = Sizes { flash: 1100, data: 100, bss: 400 };
        assert_eq!(over_limits(&s, &a), vec!["flash 1100 B > 1000 B".to_string()]);
        assert!(
            over_limits(&s, &SizeArgs { flash_max: Some(1100), ram_max: Some(500), ..a.clone() }).is_empty()
        );
        assert_eq!(args(&[]).unwrap(), SizeArgs::default());
        assert!(args(&["--flash-max"]).is_err());
        assert!(args(&["--ram-max", "lots"]).is_err());
        assert!(args(&["a.elf", "b.elf"]).is_err());
        assert!(args(&["--stack"]).is_err());
        assert_eq!(args(&["--features", "onboard-log"]).unwrap().features.as_deref(), Some("onboard-log"));
        assert!(args(&["--features"]).is_err());
        assert!(args(&["a.elf", "--features", "onboard-log"]).is_err());
    }
}
