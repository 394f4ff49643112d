//! A recording's streams merged in time, one place for everything that
//! plays recorded protocol states and commands beside samples or frames
//! (`exo fit` feeding the identifier, the driver's replay): before each
//! sample, every protocol state and command stamped at or before it, states
//! before commands at equal stamps (the controller publishes the state
//! before the command of the same tick).

use exo_messages::{ActuatorCommand, ProtocolState};

/// A recorded protocol state or command, as the cursor hands it over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Played<'a> {
    /// A protocol state.
    Protocol(&'a ProtocolState),
    /// A command.
    Command(&'a ActuatorCommand),
}

/// A cursor over time-ordered protocol states and commands.
#[derive(Debug, Clone)]
pub struct Merge<'a> {
    protocol: &'a [ProtocolState],
    commands: &'a [ActuatorCommand],
    next_protocol: usize,
    next_command: usize,
}

impl<'a> Merge<'a> {
    /// A cursor at the start of both streams.
    pub fn new(protocol: &'a [ProtocolState], commands: &'a [ActuatorCommand]) -> Self {
        Merge {
            protocol,
            commands,
            next_protocol: 0,
            next_command: 0,
        }
    }

    /// Hands every state, then every command, stamped at or before
    /// `stamp_ns` and not handed yet; stops at the first error.
    pub fn up_to<E>(
        &mut self,
        stamp_ns: u64,
        mut play: impl FnMut(Played<'a>) -> Result<(), E>,
    ) -> Result<(), E> {
        while let Some(p) = self
            .protocol
            .get(self.next_protocol)
            .filter(|p| p.stamp_ns <= stamp_ns)
        {
            play(Played::Protocol(p))?;
            self.next_protocol += 1;
        }
        while let Some(c) = self
            .commands
            .get(self.next_command)
            .filter(|c| c.stamp_ns <= stamp_ns)
        {
            play(Played::Command(c))?;
            self.next_command += 1;
        }
        Ok(())
    }

    /// A cursor at `position` (from [`Merge::position`]), to go on where
    /// an earlier cursor over the same streams stopped.
    pub fn at(
        protocol: &'a [ProtocolState],
        commands: &'a [ActuatorCommand],
        position: (usize, usize),
    ) -> Self {
        Merge {
            protocol,
            commands,
            next_protocol: position.0.min(protocol.len()),
            next_command: position.1.min(commands.len()),
        }
    }

    /// How far the cursor is: (protocol states, commands) handed.
    pub fn position(&self) -> (usize, usize) {
        (self.next_protocol, self.next_command)
    }

    /// The protocol states not handed yet (after the last sample).
    pub fn remaining_protocol(&self) -> &'a [ProtocolState] {
        &self.protocol[self.next_protocol..]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_and_commands_come_before_the_sample_they_precede() {
        let p = |t| ProtocolState {
            stamp_ns: t,
            ..Default::default()
        };
        let c = |t| ActuatorCommand {
            stamp_ns: t,
            ..Default::default()
        };
        let protocol = [p(0), p(20), p(35)];
        let commands = [c(0), c(10), c(20), c(30)];
        let mut m = Merge::new(&protocol, &commands);
        let mut seen = Vec::new();
        for sample in [0u64, 10, 20, 30] {
            m.up_to(sample, |x| -> Result<(), ()> {
                seen.push(match x {
                    Played::Protocol(p) => ('p', p.stamp_ns),
                    Played::Command(c) => ('c', c.stamp_ns),
                });
                Ok(())
            })
            .unwrap();
            seen.push(('s', sample));
        }
        assert_eq!(
            seen,
            [
                ('p', 0),
                ('c', 0),
                ('s', 0),
                ('c', 10),
                ('s', 10),
                ('p', 20),
                ('c', 20),
                ('s', 20),
                ('c', 30),
                ('s', 30)
            ]
        );
        assert_eq!(m.remaining_protocol(), &[p(35)]);
        assert_eq!(m.position(), (2, 4));
        let resumed = Merge::at(&protocol, &commands, m.position());
        assert_eq!(resumed.remaining_protocol(), &[p(35)]);
        assert_eq!(Merge::at(&protocol, &commands, (9, 9)).position(), (3, 4));
    }
}
