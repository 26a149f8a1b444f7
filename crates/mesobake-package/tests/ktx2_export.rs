//! KTX2 files of every texture format a package uses, read back by the `ktx2` crate: header,
//! level data and the data format descriptor (against the crate's own descriptor for the
//! format, derived from Khronos' tables independently of our writer).

#[path = "support/mod.rs"]
mod support;

use mesobake_package::Package;
use mesobake_package::ktx2::{vk_format, write};
use mesobake_package::manifest::TextureDimension;
use mesobake_package::quantize::Quantization;

#[test]
fn every_texture_section_reads_back_with_the_ktx2_crate() {
    // Ranks 5 and 6 end in a one- and a two-channel group: every format of each quantization.
    let mut packages = vec![support::pillars()];
    for q in Quantization::ALL {
        packages.extend([support::random_svd(5, q), support::random_svd(6, q)]);
    }
    let mut formats = std::collections::BTreeSet::new();
    for bytes in packages {
        let pkg = Package::parse(bytes).unwrap();
        for section in &pkg.manifest().sections {
            let (t, data) = (section.texture, pkg.section(&section.name).unwrap());
            let file = write(&t, data).unwrap();
            let reader =
                ktx2::Reader::new(&file[..]).unwrap_or_else(|e| panic!("{}: {e:?}", section.name));
            let h = reader.header();
            let format = h.format.expect("a known format");
            assert_eq!(format.value(), vk_format(t.format), "{}", section.name);
            let depth = match t.dimension {
                TextureDimension::D3 => t.depth,
                _ => 0,
            };
            assert_eq!(
                (h.pixel_width, h.pixel_height, h.pixel_depth),
                (t.width, t.height, depth)
            );
            assert_eq!((h.layer_count, h.face_count, h.level_count), (0, 1, 1));
            assert!(h.supercompression_scheme.is_none());
            let levels: Vec<_> = reader.levels().collect();
            assert_eq!(levels.len(), 1);
            assert_eq!(
                levels[0].data, data,
                "{}: level 0 is the section",
                section.name
            );
            let (expected, type_size) = ktx2::dfd::Basic::from_format(format).unwrap();
            assert_eq!(h.type_size, type_size, "{}", section.name);
            assert_eq!(reader.basic_dfd(), Some(&expected), "{}", section.name);
            let writer = reader.writer().unwrap().trim_end_matches('\0');
            assert!(writer.starts_with("mesobake-package "), "{writer}");
            formats.insert(format!("{:?}", t.format));
        }
    }
    // r8uint, and r, rg and rgba in u8, f16 and f32.
    assert_eq!(formats.len(), 10, "{formats:?}");
}

#[test]
fn buffers_and_short_data_have_no_ktx2_form() {
    let pkg = Package::parse(support::pillars()).unwrap();
    let section = &pkg.manifest().sections[0];
    let data = pkg.section(&section.name).unwrap();
    let e = write(&section.texture, &data[1..]).unwrap_err();
    assert!(e.to_string().contains("do not fill"), "{e}");
    let mut buffer = section.texture;
    buffer.dimension = TextureDimension::Buffer;
    let e = write(&buffer, data).unwrap_err();
    assert!(e.to_string().contains("buffer"), "{e}");
}
