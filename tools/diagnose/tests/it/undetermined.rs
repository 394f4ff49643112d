//! Undetermined is undetermined (issue 15, item 4): a value whose standard
//! error is infinite, NaN, zero or larger than the value is printed as
//! "not determined", never with a ± that claims precision.

use exo_diagnose::terms::{determined, value_pm};

#[test]
fn a_value_without_a_usable_standard_error_is_not_determined() {
    for se in [f64::INFINITY, f64::NAN, 0.0, 7.0] {
        assert!(!determined(6.73, se), "se = {se}");
        let s = value_pm(6.73, Some(se), 2, " ms");
        assert!(s.starts_with("not determined"), "se = {se}: {s}");
        assert!(!s.contains('±'), "se = {se}: {s}");
    }
    assert!(value_pm(6.73, None, 2, " ms").starts_with("not determined"));
    // An infinite value (k_c = 1/0) is never determined.
    assert!(!determined(f64::INFINITY, 1.0));
    // A determined value keeps two significant digits of its standard
    // error, however small: never "± 0.00".
    assert!(determined(6.73, 0.004));
    assert_eq!(
        value_pm(6.7312, Some(0.004), 2, " ms"),
        "6.7312 ± 0.0040 ms"
    );
    assert_eq!(value_pm(6.73, Some(0.25), 2, " ms"), "6.73 ± 0.25 ms");
}
