//! What the EtherCAT backend refuses at bring-up, naming the run-file key
//! (and the interface, the device's identity or the PDO entry's object),
//! and what it reports from the cyclic exchange.

use exo_config::PdoRole;

use super::socket::OpenError;

/// The EtherCAT backend's errors: [`super::EthercatBus::open`]'s refusals,
/// each naming the run-file key it is about, and the cyclic exchange's
/// ([`crate::HardwareBus`]'s `read` and `write`: [`EthercatError::Master`]).
#[derive(Debug, thiserror::Error)]
pub enum EthercatError {
    /// ethercrab reported an error outside the cyclic exchange.
    #[error("EtherCAT: {0}")]
    Master(String),
    /// A role the driver needs has no entry in the run file's PDO.
    #[error("{pdo}.entries: no entry with role = \"{}\"", exo_config::role_name(*role))]
    MissingRole {
        /// The PDO's key (`bus.ethercat.rx_pdo`, `bus.ethercat.tx_pdo`).
        pdo: &'static str,
        /// The role no entry has.
        role: PdoRole,
    },
    /// The interface could not be opened.
    #[error("bus.ethercat.interface = {interface:?}")]
    Interface {
        /// The interface (`bus.ethercat.interface`).
        interface: String,
        /// Why.
        source: OpenError,
    },
    /// ethercrab's frame storage was split already: a second bus in one
    /// process.
    #[error("the EtherCAT backend can be opened once per process")]
    OpenedTwice,
    /// A frame of the bring-up could not be sent on the interface.
    #[error(
        "bus.ethercat.interface = {interface:?}: cannot send on it ({}); is it up?",
        std::io::Error::from_raw_os_error(*os_error)
    )]
    CannotSend {
        /// The interface.
        interface: String,
        /// The OS error of the failed send.
        os_error: i32,
    },
    /// A step of the bring-up got no answer from the bus in time.
    #[error("bus.ethercat.interface = {interface:?}: no answer from the bus in time")]
    NoAnswer {
        /// The interface.
        interface: String,
    },
    /// The scan found no EtherCAT bus on the interface.
    #[error("bus.ethercat.interface = {interface:?}: no EtherCAT bus answered ({error})")]
    NoBus {
        /// The interface.
        interface: String,
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// `bus.ethercat.position` past the last device on the bus.
    #[error(
        "bus.ethercat.position = {position}: the bus on {interface:?} has {devices} device(s)"
    )]
    PositionPastBus {
        /// The position asked for.
        position: usize,
        /// The interface.
        interface: String,
        /// Devices the scan found.
        devices: usize,
    },
    /// ethercrab could not give the device at `bus.ethercat.position`.
    #[error("bus.ethercat.position = {position}: {error}")]
    Position {
        /// The position.
        position: usize,
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// The device at the position is not the drive the run file names (its
    /// SII identity).
    #[error(
        "{key} = {want:#x}: the device at position {position} ({name:?}) reports {got:#x} in its SII \
         (vendor {vendor_id:#x}, product {product_code:#x}, revision {revision:#x}): not the drive this run file names"
    )]
    Identity {
        /// The key that differs (`bus.ethercat.vendor_id`, `product_code`,
        /// `revision`).
        key: &'static str,
        /// The run file's value.
        want: u32,
        /// The device's.
        got: u32,
        /// The position.
        position: usize,
        /// The device's name.
        name: String,
        /// The device's vendor id (SII).
        vendor_id: u32,
        /// The device's product code (SII).
        product_code: u32,
        /// The device's revision (SII).
        revision: u32,
    },
    /// A mapped object the drive lacks (or has at another width).
    #[error(
        "{pdo}.entries[{entry}]: the drive has no {bits}-bit object {index:#06x}:{subindex} to map ({error})"
    )]
    NoObject {
        /// The PDO's key.
        pdo: &'static str,
        /// The entry's place in `entries`.
        entry: usize,
        /// The entry's width.
        bits: u8,
        /// The object's index.
        index: u16,
        /// The object's subindex.
        subindex: u8,
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// No answer to the SDO read of a mapped object.
    #[error("{pdo}.entries[{entry}]: no answer to the SDO read of {index:#06x}:{subindex}")]
    SdoReadUnanswered {
        /// The PDO's key.
        pdo: &'static str,
        /// The entry's place in `entries`.
        entry: usize,
        /// The object's index.
        index: u16,
        /// The object's subindex.
        subindex: u8,
    },
    /// The drive refused an SDO write of the mapping.
    #[error("{key}: the drive refused {index:#06x}:{subindex} ({error})")]
    SdoWriteRefused {
        /// The key written (`bus.ethercat.tx_pdo.entries[2]`, `….index`,
        /// `….entries`).
        key: String,
        /// The object's index (the PDO or its assignment).
        index: u16,
        /// The object's subindex.
        subindex: u8,
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// No answer to an SDO write of the mapping.
    #[error("{key}: no answer to the SDO write of {index:#06x}:{subindex}")]
    SdoWriteUnanswered {
        /// The key written.
        key: String,
        /// The object's index.
        index: u16,
        /// The object's subindex.
        subindex: u8,
    },
    /// The mode of operation is not mapped and the drive refused CST by SDO.
    #[error(
        "bus.ethercat.rx_pdo.entries: 0x6060 is not mapped and writing CST to it by SDO failed: {error}"
    )]
    ModeOfOperation {
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// The drive did not reach OP with the run file's mapping.
    #[error(
        "bus.ethercat.rx_pdo, bus.ethercat.tx_pdo: the drive did not reach OP with this mapping ({error})"
    )]
    NotOp {
        /// ethercrab's error.
        error: ethercrab::error::Error,
    },
    /// The mapping's size differs from the drive's process image.
    #[error(
        "{key}: the mapping is {mapped} {direction} bytes, the drive's process image {image}: the mapping does not fit this drive"
    )]
    ImageSize {
        /// The entries' key (`bus.ethercat.tx_pdo.entries`, `….rx_pdo.entries`).
        key: &'static str,
        /// `input` or `output`.
        direction: &'static str,
        /// Bytes the run file maps.
        mapped: usize,
        /// Bytes of the drive's process image.
        image: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages name the key and keep the wording of the run file's
    /// refusals (docs/faults.md, the EtherCAT tests).
    #[test]
    fn each_refusal_names_its_key() {
        let timeout = ethercrab::error::Error::SendFrame;
        let cases = [
            (
                EthercatError::MissingRole {
                    pdo: "bus.ethercat.rx_pdo",
                    role: PdoRole::TargetTorque,
                },
                "bus.ethercat.rx_pdo.entries: no entry with role = \"target_torque\"".to_owned(),
            ),
            (
                EthercatError::Identity {
                    key: "bus.ethercat.product_code",
                    want: 0x32,
                    got: 0x03b1_1002,
                    position: 0,
                    name: "drive".into(),
                    vendor_id: 0x6a5,
                    product_code: 0x03b1_1002,
                    revision: 1,
                },
                "bus.ethercat.product_code = 0x32: the device at position 0 (\"drive\") reports 0x3b11002 \
                 in its SII (vendor 0x6a5, product 0x3b11002, revision 0x1): not the drive this run file names"
                    .to_owned(),
            ),
            (
                EthercatError::NoObject {
                    pdo: "bus.ethercat.tx_pdo",
                    entry: 5,
                    bits: 32,
                    index: 0x2FFF,
                    subindex: 7,
                    error: timeout,
                },
                format!("bus.ethercat.tx_pdo.entries[5]: the drive has no 32-bit object 0x2fff:7 to map ({timeout})"),
            ),
            (
                EthercatError::ImageSize {
                    key: "bus.ethercat.tx_pdo.entries",
                    direction: "input",
                    mapped: 13,
                    image: 11,
                },
                "bus.ethercat.tx_pdo.entries: the mapping is 13 input bytes, the drive's process image 11: \
                 the mapping does not fit this drive"
                    .to_owned(),
            ),
            (
                EthercatError::PositionPastBus {
                    position: 1,
                    interface: "ecm0".into(),
                    devices: 1,
                },
                "bus.ethercat.position = 1: the bus on \"ecm0\" has 1 device(s)".to_owned(),
            ),
            (
                EthercatError::NoAnswer {
                    interface: "ecm0".into(),
                },
                "bus.ethercat.interface = \"ecm0\": no answer from the bus in time".to_owned(),
            ),
        ];
        for (e, want) in cases {
            assert_eq!(e.to_string(), want);
        }
        let e = EthercatError::Interface {
            interface: "ecm9".into(),
            source: OpenError::NoSuchInterface("ecm9".into()),
        };
        let chain = exo_service_kit::error_chain(&e);
        assert_eq!(
            chain,
            "bus.ethercat.interface = \"ecm9\": no network interface \"ecm9\" on this machine"
        );
    }
}
