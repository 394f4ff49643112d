//! The EtherCAT backend refuses, at bring-up and before the drive is ever
//! enabled, a run file the bus does not match (another device, a position
//! it lacks, a PDO mapping that does not fit, an interface that does not
//! exist or is down), naming the key. The harness is
//! [`crate::ethercat`]'s.

use std::time::{Duration, Instant};

use exo_config::RunConfig;
use exo_tests::netns::ip;

use crate::ethercat::{config, netns, open};

/// A run file spoiled by `spoil` is refused at bring-up with an error
/// naming `key`, before the drive is ever enabled.
fn refused(name: &str, key: &str, spoil: fn(&mut RunConfig)) {
    let Some(_net) = netns(module_path!(), name) else {
        return;
    };
    let mut cfg = config();
    spoil(&mut cfg);
    std::thread::sleep(Duration::from_millis(300));
    let started = Instant::now();
    match open(&cfg) {
        Ok(_) => panic!("{name}: accepted"),
        Err(e) => {
            let text = format!("{e:#}");
            assert!(text.contains(key), "{name}: {text}");
            eprintln!("{name}: refused in {:?}: {text}", started.elapsed());
        }
    }
}

#[test]
fn a_device_with_another_vendor_is_refused() {
    refused(
        "a_device_with_another_vendor_is_refused",
        "bus.ethercat.vendor_id",
        |c| c.bus.ethercat.as_mut().unwrap().vendor_id = 0x2,
    );
}

#[test]
fn a_device_with_another_product_code_is_refused() {
    // 0x32 is what the drive's object 0x1018 says; the check is on the SII.
    refused(
        "a_device_with_another_product_code_is_refused",
        "bus.ethercat.product_code",
        |c| c.bus.ethercat.as_mut().unwrap().product_code = 0x32,
    );
}

#[test]
fn a_position_the_bus_does_not_have_is_refused() {
    refused(
        "a_position_the_bus_does_not_have_is_refused",
        "bus.ethercat.position",
        |c| c.bus.ethercat.as_mut().unwrap().position = 1,
    );
}

#[test]
fn a_mapping_of_an_object_the_drive_lacks_is_refused() {
    refused(
        "a_mapping_of_an_object_the_drive_lacks_is_refused",
        "bus.ethercat.tx_pdo.entries[5]",
        |c| {
            let e = c.bus.ethercat.as_mut().unwrap();
            e.tx_pdo.entries.push(exo_config::PdoEntry {
                index: 0x2FFF,
                subindex: 7,
                bits: 32,
                role: exo_config::PdoRole::SeaDeflection,
                scale: None,
            });
        },
    );
}

#[test]
fn a_mapping_that_does_not_match_the_drives_image_is_refused() {
    // The drive's own mapping is kept (no write): its default TxPDO is
    // 6041, 6064, 606C, 6061 (11 bytes), not the run file's 13.
    refused(
        "a_mapping_that_does_not_match_the_drives_image_is_refused",
        "bus.ethercat.tx_pdo.entries",
        |c| c.bus.ethercat.as_mut().unwrap().write_mapping = false,
    );
}

#[test]
fn an_interface_that_does_not_exist_is_refused() {
    refused(
        "an_interface_that_does_not_exist_is_refused",
        "bus.ethercat.interface",
        |c| c.bus.ethercat.as_mut().unwrap().interface = "ecm9".into(),
    );
}

#[test]
fn an_interface_that_is_down_is_refused() {
    let Some(_net) = netns(module_path!(), "an_interface_that_is_down_is_refused") else {
        return;
    };
    ip("link set ecm0 down");
    let cfg = config();
    let e = open(&cfg).err().expect("accepted a downed interface");
    let text = format!("{e:#}");
    assert!(text.contains("bus.ethercat.interface"), "{text}");
}
