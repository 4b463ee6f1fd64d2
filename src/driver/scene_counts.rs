//! What a run's header counts: what one rank owns, or the whole scene once summed over
//! the ranks (a rank's model also holds its ghosts and periodic images, which their owner
//! counts).

use crate::domain::Domain;
use crate::model::Model;

/// Counts of what a rank owns (ghosts and periodic images are counted by their owner), or
/// of the whole scene when summed over the ranks ([`SceneCounts::sum_over_ranks`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SceneCounts {
    pub ranks: usize,
    pub grains: u64,
    pub elements: u64,
    pub nodes: u64,
    /// Physical mass (kg).
    pub mass: f64,
    /// Mass added by mass scaling (kg), of it at contact nodes, and the elements and
    /// contact nodes scaled.
    pub added_mass: f64,
    pub contact_added_mass: f64,
    pub scaled_elements: u64,
    pub scaled_contact_nodes: u64,
    pub surface_nodes: u64,
    pub facets: u64,
    /// The largest contact penalty ε_n (Pa/m).
    pub max_penalty: f64,
    /// The memory estimate (bytes, [`estimate_memory_bytes`]) summed over the ranks.
    pub memory_bytes: u64,
}

impl SceneCounts {
    /// What this rank owns.
    pub fn owned_by(m: &Model) -> Self {
        let held = &m.grains[..m.owned_grains];
        let surfaces = m.contact.surfaces.iter().filter(|s| s.owned);
        Self {
            ranks: 1,
            grains: held.len() as u64,
            elements: held.iter().map(|g| g.elements.len() as u64).sum(),
            nodes: held.iter().map(|g| g.nodes.len() as u64).sum(),
            mass: (held.iter())
                .map(|g| m.physical_mass[g.nodes.clone()].iter().sum::<f64>())
                .sum(),
            added_mass: m.added_mass,
            contact_added_mass: m.contact.stable_step.added_mass,
            scaled_elements: m.scaled_elements as u64,
            scaled_contact_nodes: m.contact.stable_step.scaled_nodes as u64,
            surface_nodes: surfaces.clone().map(|s| s.nodes.len() as u64).sum(),
            facets: surfaces.map(|s| s.facets.len() as u64).sum(),
            max_penalty: m.contact.stable_step.max_penalty,
            memory_bytes: estimate_memory_bytes(m) as u64,
        }
    }

    /// The counts of every rank added. All ranks must call.
    pub fn sum_over_ranks(self, domain: &Domain) -> Self {
        let sum = |v: u64| domain.sum_u64(v);
        let mut masses = [self.mass, self.added_mass, self.contact_added_mass];
        domain.sum_in_place(&mut masses);
        let mut max_penalty = [self.max_penalty];
        domain.max_in_place(&mut max_penalty);
        Self {
            ranks: domain.size(),
            grains: sum(self.grains),
            elements: sum(self.elements),
            nodes: sum(self.nodes),
            mass: masses[0],
            added_mass: masses[1],
            contact_added_mass: masses[2],
            scaled_elements: sum(self.scaled_elements),
            scaled_contact_nodes: sum(self.scaled_contact_nodes),
            surface_nodes: sum(self.surface_nodes),
            facets: sum(self.facets),
            max_penalty: max_penalty[0],
            memory_bytes: sum(self.memory_bytes),
        }
    }
}

/// Bytes held by the model, state and scratch arrays.
pub fn estimate_memory_bytes(m: &Model) -> usize {
    let ne = m.num_elements();
    let nn = m.num_nodes();
    let per_element = 16 /* tets */ + 80 /* reference */ + 2 /* law */;
    let per_node = 24 * 4 /* x0, x, v, v_next */
        + std::mem::size_of::<crate::lanes::NodeForce>()
        + 16 /* masses */
        + 1
        + 4
        + 1 /* v_next stored */;
    let plastic = if m.plastic_slot.is_empty() {
        0
    } else {
        // slot table over owned elements, and the state of each plastic element
        4 * m.plastic_slot.len()
            + std::mem::size_of::<crate::material::PlasticPoint>()
                * m.plastic_slot
                    .iter()
                    .filter(|&&s| s != crate::model::NONE)
                    .count()
    };
    ne * per_element + nn * per_node + plastic
}
