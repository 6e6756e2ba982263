//! Tests of split renders: shares tile the samples, partial files round
//! trip, and every kind of bad part is refused by name.

use super::*;
use crate::{Integrator, extract, render};
use lucent_geom::Vec3;
use lucent_scene::fixtures;

fn scene() -> RenderScene {
    let mut scene = fixtures::ball_under_sun();
    scene.environment.background = Vec3::splat(0.5);
    extract(&scene).unwrap_or_else(|e| panic!("{e}"))
}

fn settings() -> RenderSettings {
    RenderSettings {
        width: 12,
        height: 8,
        spp: 7,
        integrator: Integrator::Path,
        max_depth: 4,
        seed: 3,
        ..RenderSettings::default()
    }
}

/// The bytes of share `k` of `n`.
fn part(rs: &RenderScene, s: &RenderSettings, k: u32, n: u32, hash: u64) -> Vec<u8> {
    let share = Share::new(k, n).unwrap_or_else(|| panic!("{k}/{n}"));
    let film = render_share(rs, s, share, &|_| {}).film;
    let header = PartialHeader::new("test", hash, &format!("{s:?}"), s, share);
    let mut bytes = Vec::new();
    write_partial(&mut bytes, &header, &film).unwrap_or_else(|e| panic!("{e}"));
    bytes
}

fn merge(parts: &[(&str, &[u8])]) -> Result<Film, MergeError> {
    let mut m = Merger::new();
    for (name, bytes) in parts {
        m.add(name, &mut &bytes[..])?;
    }
    m.finish().map(|(_, f)| f)
}

#[test]
fn shares_tile_the_samples_in_order() {
    for spp in [1, 2, 7, 512, u32::MAX] {
        for n in [1, 2, 3, 7, 64] {
            let mut next = 0;
            for k in 1..=n {
                let r = Share::new(k, n).unwrap_or_else(|| panic!()).samples(spp);
                assert_eq!(r.start, next, "{k}/{n} of {spp}");
                assert!(r.len() as u64 <= u64::from(spp) / u64::from(n) + 1);
                next = r.end;
            }
            assert_eq!(next, spp);
        }
    }
    assert_eq!(Share::parse(" 2/3"), Ok(Share { index: 2, count: 3 }));
    for bad in ["0/3", "4/3", "1", "a/b", "1/0", "-1/2"] {
        assert!(Share::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn parts_in_any_order_merge_into_the_single_render() {
    let rs = scene();
    let s = settings();
    let whole = render(&rs, &s, &|_| {}).film;
    for n in [1, 2, 3, 7] {
        let parts: Vec<Vec<u8>> = (1..=n).map(|k| part(&rs, &s, k, n, 9)).collect();
        let named: Vec<(&str, &[u8])> = parts.iter().rev().map(|p| ("p", &p[..])).collect();
        let film = merge(&named).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(film, whole, "{n} parts");
        assert_eq!(film.to_srgb8(), whole.to_srgb8());
    }
    let (header, film) = read_partial(&mut &part(&rs, &s, 2, 3, 9)[..]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (header.share, header.spp, film.n_samples()),
        (Share { index: 2, count: 3 }, 7, 2)
    );
}

#[test]
fn every_truncation_and_any_flipped_byte_is_refused() {
    let rs = scene();
    let s = settings();
    let bytes = part(&rs, &s, 1, 1, 9);
    for len in (0..bytes.len()).step_by(37).chain([bytes.len() - 1]) {
        let err = read_partial(&mut &bytes[..len]).map(|_| ()).err();
        assert!(
            matches!(err, Some(PartialError::Truncated { .. } | PartialError::NotPartial)),
            "{len}: {err:?}"
        );
    }
    for at in (0..bytes.len()).step_by(101) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        assert!(read_partial(&mut &bad[..]).is_err(), "flip at {at}");
    }
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(read_partial(&mut &long[..]), Err(PartialError::TrailingBytes)));
    let mut v2 = bytes.clone();
    v2[8] = 2;
    assert!(matches!(read_partial(&mut &v2[..]), Err(PartialError::Version(2))));
    assert!(matches!(read_partial(&mut &b"P6\n"[..]), Err(PartialError::NotPartial)));
}

#[test]
fn missing_duplicate_and_foreign_parts_are_named() {
    let rs = scene();
    let s = settings();
    let (a, b, c) = (part(&rs, &s, 1, 3, 9), part(&rs, &s, 2, 3, 9), part(&rs, &s, 3, 3, 9));
    let err = |parts: &[(&str, &[u8])]| merge(parts).err().map(|e| e.to_string()).unwrap_or_default();
    assert_eq!(err(&[("a", &a), ("c", &c)]), "missing share 2/3 of 3: no part holds it");
    assert_eq!(
        err(&[("a", &a), ("b", &b), ("b2", &b), ("c", &c)]),
        "b2: share 2/3 again (already given by b)"
    );
    let other_scene = part(&rs, &s, 3, 3, 10);
    assert!(
        err(&[("a", &a), ("b", &b), ("x", &other_scene)]).starts_with("x: does not belong with a: a different scene"),
        "{}",
        err(&[("a", &a), ("x", &other_scene)])
    );
    let deeper = RenderSettings { max_depth: 5, ..s };
    let other_settings = part(&rs, &deeper, 3, 3, 9);
    assert_eq!(
        err(&[("a", &a), ("b", &b), ("y", &other_settings)]),
        "y: does not belong with a: settings differ: 'max_depth: 5' here, 'max_depth: 4' there"
    );
    let more = RenderSettings { spp: 8, ..s };
    assert_eq!(
        err(&[("a", &a), ("z", &part(&rs, &more, 2, 3, 9))]),
        "z: does not belong with a: 8 spp here, 7 there"
    );
    assert_eq!(
        err(&[("a", &a), ("w", &part(&rs, &s, 2, 4, 9))]),
        "w: does not belong with a: split in 4 shares here, 3 there"
    );
    let mut cut = c.clone();
    cut.truncate(c.len() / 2);
    assert!(err(&[("a", &a), ("b", &b), ("cut", &cut)]).starts_with("cut: truncated"));
    assert_eq!(err(&[]), "no parts to merge");
}
