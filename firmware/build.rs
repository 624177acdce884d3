//! Build script of the firmware:
//! 1. generates the firmware's MAVLink dialect (`crate::link::dialect`) from
//!    `mavlink/parapet.xml` with `mavlink-bindgen` (MAVLink 2 extension fields on), for every
//!    target. The XML holds only the messages the firmware speaks, cut verbatim out of
//!    `ardupilotmega` (see `mavlink/extract.py`), so the image links none of the ~300 other
//!    messages' code while ids, CRC_EXTRA bytes and wire layout stay those of the full dialect;
//! 2. writes the component metadata the firmware serves by MAVLink FTP (`crate::link::metadata`):
//!    `OUT_DIR/general.json` (pointing to `metadata/parameters.json` with its CRC) and
//!    `OUT_DIR/metadata.rs` (both files' bytes and MAVLink CRC32s, `metadata/crc32.rs`);
//! 3. for the Cortex-M builds, makes the board's memory map visible to cortex-m-rt's `link.x`
//!    as `memory.x` in `OUT_DIR` (`memory-f405.x` for `board-f405` and `board-qemu`,
//!    `memory-h743.x` for `board-h743`; no file named `memory.x` may lie in the workspace root,
//!    where the linker looks first: the H743 image linked the F405's map from there, `.data`
//!    in the DTCM at 0x2000_0000 that its DMA cannot reach) and adds the linker scripts (`defmt.x`
//!    only for the real boards, whose builds link defmt; `ccm.x`, generated, placing the
//!    CPU-only `.ccmram` section per board).
use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_default());
    println!("cargo:rerun-if-changed=build.rs");
    generate_dialect(&manifest, &out);
    generate_metadata(&manifest, &out);

    let target = env::var("TARGET").unwrap_or_default();
    let h743 = env::var_os("CARGO_FEATURE_BOARD_H743").is_some();
    let root_memory_x = if h743 { manifest.join("memory-h743.x") } else { manifest.join("memory-f405.x") };
    println!("cargo:rerun-if-changed={}", root_memory_x.display());
    if !target.starts_with("thumb") {
        return;
    }
    if let Err(e) = fs::copy(&root_memory_x, out.join("memory.x")) {
        println!("cargo:warning=cannot copy {}: {e}", root_memory_x.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_BOARD_F405").is_some() || h743 {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    let qemu = env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some();
    if let Err(e) = fs::write(out.join("ccm.x"), ccm_script(qemu, h743)) {
        println!("cargo:warning=cannot write ccm.x: {e}");
    }
    println!("cargo:rustc-link-arg-bins=-Tccm.x");
}

/// `ccm.x`: where the `.ccmram` section (the CPU-only memory, `src/board/ccm.rs`) goes — the
/// F405's CCM (`memory-f405.x`'s `CCMRAM`, 64 KiB at 0x1000_0000); on QEMU's netduinoplus2, which
/// models no CCM but 192 KiB of SRAM, the 64 KiB past the F405's 128 KiB (0x2002_0000), so that
/// the QEMU image's SRAM use and stack margin stay the F405's; on the H743, its `RAM`. NOLOAD:
/// the firmware zeroes it at boot.
fn ccm_script(qemu: bool, h743: bool) -> String {
    // In another region: after `.got`, past cortex-m-rt's `__ebss` and `_stack_end` (a section
    // inserted after `.bss` moves them and must stay in RAM); in RAM (the H743): after `.bss`,
    // inside cortex-m-rt's zeroed range and below the stack.
    let (memory, region, after) = if qemu {
        ("MEMORY { QEMU_CCM : ORIGIN = 0x20020000, LENGTH = 64K }\n", "QEMU_CCM", ".got")
    } else if h743 {
        ("", "RAM", ".bss")
    } else {
        ("", "CCMRAM", ".got")
    };
    format!(
        "{memory}SECTIONS\n{{\n  .ccmram (NOLOAD) : ALIGN(4)\n  {{\n    __sccmram = .;\n    \
         *(.ccmram .ccmram.*);\n    . = ALIGN(4);\n    __eccmram = .;\n  }} > {region}\n}} INSERT AFTER {after};\n"
    )
}

include!("metadata/crc32.rs");

/// `OUT_DIR/general.json` (COMP_METADATA_TYPE_GENERAL: version 1, the parameter metadata's URI
/// and CRC) and `OUT_DIR/metadata.rs` (`GENERAL_JSON`, `PARAMETERS_JSON`, their CRCs,
/// `PARAMETERS_URI`), included by `src/link/metadata.rs`.
fn generate_metadata(manifest: &std::path::Path, out: &std::path::Path) {
    let params = manifest.join("metadata/parameters.json");
    println!("cargo:rerun-if-changed={}", params.display());
    println!("cargo:rerun-if-changed={}", manifest.join("metadata/crc32.rs").display());
    let bytes = match fs::read(&params) {
        Ok(b) => b,
        Err(e) => panic!("{}: {e} (write it with `cargo xtask params --firmware`)", params.display()),
    };
    let params_uri = "mftp://[;comp=1]/parameters.json";
    let params_crc = mavlink_crc32(&bytes);
    let general = format!(
        "{{\"version\":1,\"vendorName\":\"Parapet\",\"modelName\":\"Parapet quadrotor\",\
         \"firmwareVersion\":\"{}\",\"metadataTypes\":[{{\"type\":1,\"uri\":\"{params_uri}\",\
         \"fileCrc\":{params_crc}}}]}}\n",
        env::var("CARGO_PKG_VERSION").unwrap_or_default()
    );
    let general_path = out.join("general.json");
    let code = format!(
        "/// `general.json`.\npub static GENERAL_JSON: &[u8] = include_bytes!({:?});\n\
         /// MAVLink CRC32 of `general.json`.\npub const GENERAL_CRC: u32 = {:#010x};\n\
         /// `parameters.json`.\npub static PARAMETERS_JSON: &[u8] = include_bytes!({:?});\n\
         /// MAVLink CRC32 of `parameters.json`.\npub const PARAMETERS_CRC: u32 = {params_crc:#010x};\n\
         /// `parameters.json`'s URI in `general.json`.\npub const PARAMETERS_URI: &str = {params_uri:?};\n",
        general_path.display().to_string(),
        mavlink_crc32(general.as_bytes()),
        params.display().to_string(),
    );
    for (path, text) in [(general_path.clone(), general.as_str()), (out.join("metadata.rs"), code.as_str())] {
        if let Err(e) = fs::write(&path, text) {
            panic!("{}: {e}", path.display());
        }
    }
}

/// `OUT_DIR/parapet.rs` (the bindings) and `OUT_DIR/mod.rs` (`pub mod parapet;`, included by
/// `src/link/dialect.rs`). The generated code's optional derives (`serde`, `arbitrary`, `ts-rs`,
/// under `feature = ".."` cfgs the firmware does not have) are turned off for good by rewriting
/// those cfgs to `any()` (always false), so they raise no unexpected-cfg warnings.
fn generate_dialect(manifest: &std::path::Path, out: &std::path::Path) {
    let xml = manifest.join("mavlink/parapet.xml");
    println!("cargo:rerun-if-changed={}", xml.display());
    let result = match mavlink_bindgen::generate(mavlink_bindgen::XmlDefinitions::Files(vec![&xml]), out) {
        Ok(r) => r,
        Err(e) => panic!("{}: {e}", xml.display()),
    };
    for b in &result.bindings {
        let code = match fs::read_to_string(&b.rust_module) {
            Ok(c) => c,
            Err(e) => panic!("{}: {e}", b.rust_module.display()),
        };
        let code = ["serde", "arbitrary", "ts-rs"]
            .iter()
            .fold(code, |c, f| c.replace(&format!("feature = \"{f}\""), "any()"));
        let table = extra_crc_table(&code);
        let code = code + &table;
        if let Err(e) = fs::write(&b.rust_module, code) {
            panic!("{}: {e}", b.rust_module.display());
        }
    }
    let mod_rs = "#[allow(non_camel_case_types, non_snake_case, missing_docs, unused_imports)]\n\
                  #[allow(clippy::all, clippy::pedantic, clippy::panic, clippy::unwrap_used, clippy::expect_used)]\n\
                  pub mod parapet;\n";
    if let Err(e) = fs::write(&result.mod_rs, mod_rs) {
        panic!("{}: {e}", result.mod_rs.display());
    }
}

/// `EXTRA_CRCS`: `(ID, EXTRA_CRC)` of every message of the generated dialect, in the order of
/// its `extra_crc` match (the framer looks ids up in this table, sorted, instead of the
/// generated match: about 500 bytes less on the F405). Built from the generated match's arms
/// `NAME_DATA :: ID => NAME_DATA :: EXTRA_CRC`; an empty table if the generator's layout changes
/// (then `firmware/src/link/messages.rs`'s test against the match fails).
fn extra_crc_table(code: &str) -> String {
    let body = code
        .split_once("fn extra_crc (id : u32) -> u8 { match id {")
        .and_then(|(_, rest)| rest.split_once('}'))
        .map_or("", |(arms, _)| arms);
    let entries: Vec<String> = body
        .split(" , ")
        .filter_map(|arm| {
            let (lhs, rhs) = arm.trim().split_once(" => ")?;
            let name = lhs.strip_suffix(" :: ID")?;
            (rhs.trim() == format!("{name} :: EXTRA_CRC")).then(|| format!("({name}::ID, {name}::EXTRA_CRC)"))
        })
        .collect();
    format!(
        "\n/// `(ID, EXTRA_CRC)` of every message of this dialect (build.rs).\npub const EXTRA_CRCS: [(u32, u8); {}] = [{}];\n",
        entries.len(),
        entries.join(", ")
    )
}
