//! Package edits that keep every checksum valid, as a malicious or buggy writer would make
//! them: shared by the tests of package validation and the mutation fuzzer.

/// Rewrites the header's checksum after an edit, as a malicious or buggy writer would.
pub fn reseal_header(bytes: &mut [u8]) {
    let crc = crc32fast::hash(&bytes[..60]);
    bytes[60..64].copy_from_slice(&crc.to_le_bytes());
}

/// Replaces the manifest with `edit(manifest)`, keeping every checksum valid.
pub fn with_manifest(bytes: &[u8], edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let offset = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&bytes[offset..]).unwrap();
    edit(&mut json);
    let text = serde_json::to_vec(&json).unwrap();
    let mut out = bytes[..offset].to_vec();
    out.extend_from_slice(&text);
    let total = out.len() as u64;
    out[24..32].copy_from_slice(&(text.len() as u64).to_le_bytes());
    out[32..36].copy_from_slice(&crc32fast::hash(&text).to_le_bytes());
    out[40..48].copy_from_slice(&total.to_le_bytes());
    reseal_header(&mut out);
    out
}
