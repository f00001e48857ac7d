//! The built Cortex-M images (the QEMU board's and the STM32F4 board's) hold no `RefCell`
//! panic path (`panic_already_borrowed`): the interrupt glue shares the app through
//! `isr::Shared`, which refuses a second borrower instead of panicking. The test builds the
//! firmware's release images itself (installing the ARM target if it is missing, as the PIL
//! tests do) into `target/firmware`, the directory every host-side firmware build shares,
//! and reads their symbol tables. The same check by hand:
//! `llvm-nm -C target/thumbv7em-none-eabihf/release/fw-bench | grep borrowed`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

/// Symbol names that must not be linked into a firmware image.
const FORBIDDEN: &[&str] = &["panic_already_borrowed", "panic_already_mutably_borrowed"];

fn u16_at(b: &[u8], at: usize) -> usize {
    usize::from(u16::from_le_bytes([b[at], b[at + 1]]))
}

fn u32_at(b: &[u8], at: usize) -> usize {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize
}

/// Every symbol name in the `.symtab` of a 32-bit little-endian ELF.
fn symbol_names(elf: &[u8]) -> Vec<String> {
    assert_eq!(&elf[..4], b"\x7fELF", "not an ELF file");
    assert_eq!(elf[4], 1, "not a 32-bit ELF");
    let (shoff, shentsize, shnum) = (u32_at(elf, 0x20), u16_at(elf, 0x2E), u16_at(elf, 0x30));
    let section = |i: usize| shoff + i * shentsize;
    let mut names = Vec::new();
    for i in 0..shnum {
        let sh = section(i);
        // SHT_SYMTAB = 2; its sh_link names the string table.
        if u32_at(elf, sh + 4) != 2 {
            continue;
        }
        let (off, size, link, entsize) = (
            u32_at(elf, sh + 16),
            u32_at(elf, sh + 20),
            u32_at(elf, sh + 24),
            u32_at(elf, sh + 36).max(16),
        );
        let strtab = u32_at(elf, section(link) + 16);
        for sym in (off..off + size).step_by(entsize) {
            let start = strtab + u32_at(elf, sym);
            let end = elf[start..]
                .iter()
                .position(|&c| c == 0)
                .map_or(start, |n| start + n);
            names.push(String::from_utf8_lossy(&elf[start..end]).into_owned());
        }
    }
    names
}

#[test]
fn firmware_images_hold_no_refcell_panic_path() {
    // The images are read while the build lock is held, so no feature build replaces one.
    let images = pil_host::with_all_images(|release| {
        let read = |image: &str| {
            let path = release.join(image);
            std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        };
        Ok(["firmware", "fw-bench", "fw-lil", "pil", "board"].map(|image| (image, read(image))))
    })
    .unwrap();
    // The STM32F4 board's image (its own features; copied out of the build directory, so
    // no later build replaces it while it is read).
    let stm32 = pil_host::image::build_stm32_image_for(None).unwrap();
    let stm32 = std::fs::read(&stm32).unwrap_or_else(|e| panic!("{}: {e}", stm32.display()));
    let mut checked = 0;
    for (image, elf) in images.into_iter().chain([("stm32f4", stm32)]) {
        let names = symbol_names(&elf);
        assert!(
            names
                .iter()
                .any(|n| n.contains("TIMER0") || n.contains("TIM6")),
            "{image}: no current-loop handler among {} symbols: symbol table not read",
            names.len()
        );
        for bad in FORBIDDEN {
            let hits: Vec<_> = names.iter().filter(|n| n.contains(bad)).collect();
            assert!(hits.is_empty(), "{image} links {hits:?}");
        }
        checked += 1;
    }
    assert_eq!(checked, 6);
    eprintln!("{checked} firmware images checked for {FORBIDDEN:?}");
}
