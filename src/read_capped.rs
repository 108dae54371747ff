//! Reading input files under a size cap: a huge file named as a scene, sky or config is
//! refused by its size, and a device file (`/dev/zero`), FIFO or socket before it is opened
//! (opening a FIFO without a writer would block for ever), instead of being read without end.

use std::io::Read;
use std::path::Path;

/// Largest config file read (a CAVE's config is a few kilobytes; 64 walls are ~20 KB).
pub const MAX_CONFIG_BYTES: u64 = 4 << 20;

/// Reads at most `max_bytes` of `path`; a longer file is an [`std::io::ErrorKind::FileTooLarge`]
/// error saying the cap (so the caller's "cannot read FILE: …" message names both). Only
/// regular files are read (checked before opening); the read stops at the cap even if the
/// file grows meanwhile.
/// `limit` names where the cap is set, for the message.
pub fn read_capped(path: &Path, max_bytes: u64, limit: &str) -> std::io::Result<Vec<u8>> {
    let kind = std::fs::metadata(path)?.file_type();
    if kind.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory, not a file",
        ));
    }
    if !kind.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "is not a regular file (a device, FIFO or socket); only files are read",
        ));
    }
    let file = std::fs::File::open(path)?;
    let too_large = |size: String| {
        std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!(
                "{size} is over the limit of {} ({limit})",
                human_bytes(max_bytes)
            ),
        )
    };
    let size = file.metadata()?.len();
    if size > max_bytes {
        return Err(too_large(human_bytes(size)));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large("its content".into()));
    }
    Ok(bytes)
}

/// [`read_capped`] as UTF-8 text.
pub fn read_capped_text(path: &Path, max_bytes: u64, limit: &str) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, max_bytes, limit)?)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "is not UTF-8 text"))
}

/// `1536` → `"1.5 KiB"`.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_files_and_large_files_stop_at_the_cap() {
        let err = read_capped(Path::new("/dev/zero"), 1 << 20, "test").unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        let dir = std::env::temp_dir().join(format!("omnicave-cap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("big.bin");
        std::fs::write(&file, vec![7u8; 4096]).unwrap();
        assert!(read_capped(&file, 4095, "test").is_err());
        assert_eq!(read_capped(&file, 4096, "test").unwrap().len(), 4096);
        assert!(read_capped(&dir, 4096, "test").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(human_bytes(512), "512 bytes");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(3 << 30), "3.0 GiB");
    }
}
