//! What the PLY and PCD targets check of an accepted cloud (included by both with `#[path]`).

use cloud_io::{LoadOptions, LoadedCloud, NonFinitePolicy, ParseError};
use mmt::cloud::{CloudFrame, Pose};

/// Parses `data` with both non-finite policies and checks what is accepted: every point finite
/// and in range (so it makes a `CloudFrame`), the policies agree, `parse_cloud` agrees when it
/// detects `format`, and `encode` gives the same points back bit for bit in every encoding.
pub fn check(
    data: &[u8],
    parse: fn(&[u8], LoadOptions) -> Result<LoadedCloud, ParseError>,
    detected: bool,
    encoders: &[fn(&[[f32; 3]]) -> Vec<u8>],
) {
    let reject = parse(data, LoadOptions::default());
    let skip = parse(
        data,
        LoadOptions {
            non_finite: NonFinitePolicy::Skip,
        },
    );
    if detected {
        // Compared as text: an error may carry the NaN it refused, and NaN != NaN.
        let direct = cloud_io::parse_cloud(data, LoadOptions::default());
        assert_eq!(format!("{direct:?}"), format!("{reject:?}"));
    }
    if let Ok(cloud) = &reject {
        assert_eq!(cloud.skipped_non_finite, 0);
        assert_eq!(
            skip.as_ref(),
            Ok(cloud),
            "a file Reject accepts, Skip reads the same"
        );
    }
    let Ok(cloud) = skip else { return };
    let limit = CloudFrame::MAX_ABS_COORDINATE_M;
    for p in &cloud.points {
        assert!(p.iter().all(|c| c.is_finite() && c.abs() <= limit), "{p:?}");
    }
    if let Some(pose) = cloud.viewpoint {
        assert!(pose.is_finite());
    }
    let n = cloud.points.len();
    let frame = CloudFrame::new(
        cloud.points.clone(),
        0,
        cloud.viewpoint.unwrap_or(Pose::IDENTITY),
    );
    assert!(frame.is_ok(), "an accepted cloud makes a frame: {frame:?}");
    let bits = |points: &[[f32; 3]]| -> Vec<[u32; 3]> {
        points.iter().map(|p| p.map(f32::to_bits)).collect()
    };
    for encode in encoders {
        let again = parse(&encode(&cloud.points), LoadOptions::default())
            .unwrap_or_else(|e| panic!("re-encoded {n} accepted points do not parse: {e}"));
        assert_eq!(bits(&again.points), bits(&cloud.points));
    }
}
