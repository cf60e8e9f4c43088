#![no_main]
//! Arbitrary text as a trajectory: no panic; accepted files have strictly
//! increasing finite times and survive a save/parse round trip.
use hilcam_fuzz::pose::trajectory::Trajectory;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(s) = Trajectory::parse(text, Path::new("fuzz.csv")) {
        assert!(s.windows(2).all(|w| w[0].time_s < w[1].time_s));
        let again = Trajectory::parse(&Trajectory::to_csv(&s), Path::new("again.csv")).unwrap();
        assert_eq!(again, s);
    }
});
