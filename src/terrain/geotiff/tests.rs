//! Unit tests of the GeoTIFF reader and writer.

use std::io::Cursor;

use tiff::encoder::{TiffEncoder, colortype};

use super::write::geo_keys_for;
use super::*;
use crate::MOON_RADIUS_M;

fn grid(rows: usize, cols: usize) -> GridGeometry {
    GridGeometry {
        rows,
        cols,
        x_left_m: -1500.0,
        y_top_m: 2500.0,
        px_x_m: 100.0,
        px_y_m: 100.0,
    }
}

#[test]
fn f32_round_trip_is_exact_with_holes_and_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.tif");
    let g = grid(7, 5);
    let mut values: Vec<f32> = (0..35).map(|i| i as f32 * 1.25 - 7.0).collect();
    values[3] = f32::NAN;
    let dem = Dem {
        grid: g,
        projection: Projection::LOLA_SOUTH_POLAR,
        heights_m: values.clone(),
        name: "t".into(),
    };
    write_dem(
        &path,
        &dem,
        &[("tool", "penumbra <0.1> & co"), ("note", "h\u{e9}")],
    )
    .unwrap();
    let (back, items) = read_geotiff_with_metadata(&path).unwrap();
    assert_eq!(back.grid, g);
    assert_eq!(back.projection, Projection::LOLA_SOUTH_POLAR);
    for (a, b) in back.heights_m.iter().zip(&values) {
        assert!(a == b || (a.is_nan() && b.is_nan()), "{a} vs {b}");
    }
    assert_eq!(
        items,
        vec![
            ("tool".to_string(), "penumbra <0.1> & co".to_string()),
            ("note".to_string(), "h\u{e9}".to_string())
        ]
    );
}

#[test]
fn u16_u8_and_equirectangular_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let g = grid(4, 6);
    let eqc = Projection::Equirectangular {
        lon0_deg: 180.0,
        lat_ts_deg: 10.0,
        radius_m: MOON_RADIUS_M,
    };
    let p16 = dir.path().join("u16.tif");
    let v16: Vec<u16> = (0..24).map(|i| i * 2700).collect();
    write_geotiff(&p16, &g, &eqc, &v16, Some(0), &[], BandInfo::default()).unwrap();
    let d = read_geotiff(&p16).unwrap();
    assert_eq!(d.projection, eqc);
    assert_eq!(d.grid, g);
    assert!(d.heights_m[0].is_nan(), "nodata 0 becomes a hole");
    for (a, b) in d.heights_m.iter().zip(&v16).skip(1) {
        assert_eq!(*a, f32::from(*b));
    }
    let p8 = dir.path().join("u8.tif");
    let v8: Vec<u8> = (0..24).map(|i| i * 10).collect();
    write_geotiff(
        &p8,
        &g,
        &Projection::LOLA_SOUTH_POLAR,
        &v8,
        None,
        &[],
        BandInfo::default(),
    )
    .unwrap();
    let d = read_geotiff(&p8).unwrap();
    for (a, b) in d.heights_m.iter().zip(&v8) {
        assert_eq!(*a, f32::from(*b));
    }
}

#[test]
fn geo_keys_round_trip_through_the_parser() {
    for p in [
        Projection::LOLA_SOUTH_POLAR,
        Projection::PolarStereographic {
            south: false,
            lon0_deg: 45.0,
            k0: 0.994,
            radius_m: 1_737_150.0,
        },
        Projection::Equirectangular {
            lon0_deg: 0.0,
            lat_ts_deg: -85.0,
            radius_m: MOON_RADIUS_M,
        },
    ] {
        let (dir, doubles, ascii) = geo_keys_for(&p);
        let keys = parse_geo_keys(&dir, &doubles, &ascii).unwrap();
        let crs = projection_from_geo_keys(&keys).unwrap();
        assert_eq!(crs.projection, p);
        assert_eq!((crs.false_easting_m, crs.false_northing_m), (0.0, 0.0));
    }
}

#[test]
fn proj_string_fallback_and_rejections() {
    let crs = crs_from_proj_string(
        "+proj=stere +lat_0=-90 +lon_0=0 +k=1 +x_0=0 +y_0=0 +R=1737400 +units=m",
    )
    .unwrap();
    assert_eq!(crs.projection, Projection::LOLA_SOUTH_POLAR);
    assert!(crs_from_proj_string("+proj=stere +lat_0=-45 +R=1737400").is_err());
    assert!(crs_from_proj_string("+proj=stere +lat_0=-90 +R=6378137").is_err());
    assert!(crs_from_proj_string("+proj=merc +R=1737400").is_err());
    // An Earth ellipsoid through GeoKeys.
    let mut keys = BTreeMap::new();
    keys.insert(KEY_MODEL_TYPE, GeoKeyValue::Short(1));
    keys.insert(
        KEY_PROJ_COORD_TRANS,
        GeoKeyValue::Short(CT_POLAR_STEREOGRAPHIC),
    );
    keys.insert(KEY_GEOG_ELLIPSOID, GeoKeyValue::Short(7030));
    let err = projection_from_geo_keys(&keys).unwrap_err();
    assert!(err.contains("7030"), "{err}");
    keys.clear();
    keys.insert(KEY_PROJECTED_CS_TYPE, GeoKeyValue::Short(3031));
    let err = projection_from_geo_keys(&keys).unwrap_err();
    assert!(err.contains("EPSG:3031"), "{err}");
}

#[test]
fn pixel_is_point_shifts_half_a_pixel_and_false_origin_is_removed() {
    let g = grid_from_tags(
        10,
        10,
        Some(&[240.0, 240.0, 0.0]),
        Some(&[0.0, 0.0, 0.0, -184200.0, 184200.0, 0.0]),
        None,
        true,
        (1000.0, -2000.0),
    )
    .unwrap();
    assert_eq!(
        (g.x_left_m, g.y_top_m),
        (-184320.0 - 1000.0, 184320.0 + 2000.0)
    );
    let m = [
        10.0, 0.0, 0.0, -5.0, 0.0, -20.0, 0.0, 7.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    let g = grid_from_tags(2, 3, None, None, Some(&m), false, (0.0, 0.0)).unwrap();
    assert_eq!(
        (g.x_left_m, g.y_top_m, g.px_x_m, g.px_y_m),
        (-5.0, 7.0, 10.0, 20.0)
    );
}

#[test]
fn gdal_metadata_scale_offset_items_are_parsed() {
    let xml = r#"<GDALMetadata>
  <Item name="units">m</Item>
  <Item name="OFFSET" sample="0" role="offset">10</Item>
  <Item name="SCALE" sample="0" role="scale">0.5</Item>
</GDALMetadata>"#;
    let items = parse_gdal_metadata(xml);
    assert_eq!(items.len(), 3);
    assert_eq!(items[2].role.as_deref(), Some("scale"));
    assert_eq!(items[2].value, "0.5");
    assert_eq!(parse_nodata("nan").map(f64::is_nan), Some(true));
    assert_eq!(parse_nodata("-32768"), Some(-32768.0));
}

#[test]
fn int16_with_scale_offset_and_nodata_is_decoded() {
    // Build an int16 GeoTIFF by hand with the tiff encoder, as LOLA's int16 (0.5 m) products
    // are stored: height = raw * 0.5 + 1737400 - 1737400 (offset 0 here, 10 m to test it).
    let raw: Vec<i16> = vec![-32768, -2, 0, 3, 100, 200, 300, 400, -500, 1, 2, 32767];
    let (dir, doubles, ascii) = geo_keys_for(&Projection::LOLA_SOUTH_POLAR);
    let mut bytes = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut bytes).unwrap();
        let mut img = enc.new_image::<colortype::GrayI16>(4, 3).unwrap();
        let d = img.encoder();
        d.write_tag(Tag::ModelPixelScaleTag, &[100.0, 100.0, 0.0][..])
            .unwrap();
        d.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, -1500.0, 2500.0, 0.0][..],
        )
        .unwrap();
        d.write_tag(Tag::GeoKeyDirectoryTag, &dir[..]).unwrap();
        d.write_tag(Tag::GeoDoubleParamsTag, &doubles[..]).unwrap();
        d.write_tag(Tag::GeoAsciiParamsTag, ascii.as_str()).unwrap();
        d.write_tag(Tag::Unknown(TAG_GDAL_NODATA), "-32768")
            .unwrap();
        d.write_tag(
            Tag::Unknown(TAG_GDAL_METADATA),
            r#"<GDALMetadata><Item name="SCALE" sample="0" role="scale">0.5</Item><Item name="OFFSET" sample="0" role="offset">10</Item></GDALMetadata>"#,
        )
        .unwrap();
        img.write_data(&raw).unwrap();
    }
    let bytes = bytes.into_inner();
    let (dem, _) = read_geotiff_from(Cursor::new(bytes), "i16").unwrap();
    assert!(dem.heights_m[0].is_nan());
    for (h, r) in dem.heights_m.iter().zip(&raw).skip(1) {
        assert_eq!(f64::from(*h), f64::from(*r) * 0.5 + 10.0);
    }
}

#[test]
fn cog_tiles_overviews_and_predictors_round_trip_exactly() {
    // 600 x 530: 3 x 3 tiles with partial edges, two overview levels (300 x 265, 150 x 133).
    let dir = tempfile::tempdir().unwrap();
    let g = grid(530, 600);
    let mut heights: Vec<f32> = (0..530 * 600)
        .map(|i| ((i % 600) as f32 * 0.37).sin() * 1200.0 + (i / 600) as f32 * 0.5 - 3000.25)
        .collect();
    for h in heights.iter_mut().step_by(97) {
        *h = f32::NAN;
    }
    let dem = Dem {
        grid: g,
        projection: Projection::LOLA_SOUTH_POLAR,
        heights_m: heights.clone(),
        name: "t".into(),
    };
    let path = dir.path().join("cog.tif");
    write_dem(&path, &dem, &[]).unwrap();
    let back = read_geotiff(&path).unwrap();
    assert_eq!(back.grid, g);
    for (a, b) in back.heights_m.iter().zip(&heights) {
        assert!(
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            "{a} vs {b}"
        );
    }
    // The layout: tiled, Deflate, floating-point predictor, overviews after the main image.
    let bytes = std::fs::read(&path).unwrap();
    let mut d = tiff::decoder::Decoder::new(std::io::Cursor::new(&bytes)).unwrap();
    assert_eq!(d.get_chunk_type(), ChunkType::Tile);
    assert_eq!(
        d.find_tag_unsigned::<u16>(Tag::Compression).unwrap(),
        Some(8)
    );
    assert_eq!(d.find_tag_unsigned::<u16>(Tag::Predictor).unwrap(), Some(3));
    let mut sizes = vec![d.dimensions().unwrap()];
    while d.more_images() {
        d.next_image().unwrap();
        sizes.push(d.dimensions().unwrap());
    }
    assert_eq!(sizes, vec![(600, 530), (300, 265), (150, 133)]);
    // The last overview is the mean of the valid pixels of each 4 x 4 block of the first.
    let DecodingResult::F32(ovr) = d.read_image().unwrap() else {
        panic!("f32 overview")
    };
    // The mean of the valid pixels of the 2 x 2 block under overview pixel (r, c) of a
    // `cols`-wide, `rows`-high image (`NaN` where none is valid).
    let block_mean = |v: &[f32], (rows, cols): (usize, usize), r: usize, c: usize| {
        let v: Vec<f64> = [(0, 0), (0, 1), (1, 0), (1, 1)]
            .iter()
            .map(|(dr, dc)| (2 * r + dr, 2 * c + dc))
            .filter(|&(rr, cc)| rr < rows && cc < cols)
            .map(|(rr, cc)| f64::from(v[rr * cols + cc]))
            .filter(|h| !h.is_nan())
            .collect();
        (v.iter().sum::<f64>() / v.len() as f64) as f32
    };
    let mut lvl1 = vec![f32::NAN; 300 * 265];
    for r in 0..265 {
        for c in 0..300 {
            lvl1[r * 300 + c] = block_mean(&heights, (530, 600), r, c);
        }
    }
    let at = |r: usize, c: usize| block_mean(&lvl1, (265, 300), r, c);
    assert_eq!(ovr.len(), 150 * 133);
    for (r, c) in [(0, 0), (7, 149), (132, 0), (132, 149), (60, 77)] {
        assert_eq!(ovr[r * 150 + c], at(r, c), "overview pixel ({r}, {c})");
    }
    // u8 classes keep their values in the overviews (first valid pixel of each block).
    let classes: Vec<u8> = (0..530 * 600).map(|i| [0u8, 1, 255][i % 7 % 3]).collect();
    let p8 = dir.path().join("mask.tif");
    write_geotiff(
        &p8,
        &g,
        &Projection::LOLA_SOUTH_POLAR,
        &classes,
        Some(255),
        &[],
        BandInfo::default(),
    )
    .unwrap();
    let mut d = tiff::decoder::Decoder::new(std::fs::File::open(&p8).unwrap()).unwrap();
    let DecodingResult::U8(full) = d.read_image().unwrap() else {
        panic!("u8")
    };
    assert_eq!(full, classes);
    d.next_image().unwrap();
    let DecodingResult::U8(ovr) = d.read_image().unwrap() else {
        panic!("u8")
    };
    assert!(ovr.iter().all(|v| [0, 1, 255].contains(v)));
}
