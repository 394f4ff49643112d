//! `exo-tunnel`: the run's channels to another host over Zenoh
//! ([`exo_tunnel::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_tunnel::process::TunnelProcess>()
}
