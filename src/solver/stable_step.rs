//! The explicit time step and mass scaling of a model (set up once, before the run).
//!
//! Each element's own critical step comes from its exact largest stiffness eigenvalue with
//! lumped mass, Δt_e = 2/√(λ_max/m) (`crate::element::max_stiffness_eigenvalue`; 0.565 h/c_p
//! for a regular tet). With `simulation.target_dt` an element whose Δt_e is below
//! target_dt/safety has its density raised by (target/Δt_e)² so that target_dt is stable
//! ("mass scaling"; the added mass is reported). Contact penalty springs add
//! ω² = ω_el² + 2k/m at surface nodes that can touch another grain, and a lagged dashpot of
//! ratio ζ lowers the limit to (2/ω)(√(1+ζ²) − ζ) (see `crate::contact`); with a target step
//! those nodes are mass-scaled too.

use crate::contact::{ContactModel, StableStepReport, NONE};
use crate::element::max_stiffness_eigenvalue;
use crate::error::InputError;
use crate::model::Model;
use crate::scene::Simulation;

/// Sets `model.mass`, `dt`, `dt_stable`, `dt_critical_element`, `added_mass`,
/// `scaled_elements` and the contact stable-step report from the simulation settings.
/// Fails when a prescribed `simulation.dt` exceeds the stable step.
pub fn set_time_step_and_mass_scaling(
    model: &mut Model,
    sim: &Simulation,
    file: &str,
) -> Result<(), InputError> {
    let elem_dt: Vec<f64> = model
        .tet_reference
        .iter()
        .zip(&model.tet_law)
        .map(|(r, &l)| {
            let law = &model.laws[l as usize];
            let k = max_stiffness_eigenvalue(&r, law.lambda, law.mu);
            let m = model.materials[l as usize].density * r.volume / 4.0;
            2.0 / (k / m).sqrt()
        })
        .collect();
    let (dt_critical_element, dt_crit) = elem_dt.iter().enumerate().fold(
        (0, f64::INFINITY),
        |acc, (e, &d)| if d < acc.1 { (e, d) } else { acc },
    );
    let dt_stable_elements = sim.dt_safety * dt_crit;

    // Mass scaling: raise an element's density so its own stable step reaches target_dt.
    let mut mass = vec![0.0; model.num_nodes()];
    let mut added_mass = 0.0;
    let mut scaled_elements = 0;
    let target = sim.target_dt.map(|t| t / sim.dt_safety);
    let mut elem_scale = vec![1.0; model.num_elements()];
    for (e, t) in model.tets.iter().enumerate() {
        let rho = model.materials[model.tet_law[e] as usize].density;
        let m_phys = rho * model.tet_reference.get(e).volume / 4.0;
        let scale = match target {
            Some(tgt) if elem_dt[e] < tgt => (tgt / elem_dt[e]).powi(2),
            _ => 1.0,
        };
        // ghosts and images are scaled like their owners but reported by them
        if e < model.owned_elements {
            added_mass += 4.0 * m_phys * (scale - 1.0);
            scaled_elements += usize::from(scale > 1.0);
        }
        elem_scale[e] = scale;
        for &node in t {
            mass[node as usize] += m_phys * scale;
        }
    }

    // Contact penalty springs in the stable step (and contact-node mass scaling towards
    // target_dt).
    let dt_contact = account_contact_springs(
        &mut model.contact,
        &model.tets,
        &elem_dt,
        &elem_scale,
        &model.physical_mass,
        &mut mass,
        sim.dt_safety,
        sim.target_dt,
        model.owned_nodes,
    );
    added_mass += model.contact.stable_step.added_mass;
    let dt_stable = dt_stable_elements.min(dt_contact);

    // After scaling every element's (and contact node's) own step is ≥ target_dt/safety,
    // so target_dt is stable.
    let scaled_dt = sim.target_dt.unwrap_or(dt_stable);
    let dt = match sim.dt {
        Some(d) => {
            if d > scaled_dt * (1.0 + 1e-12) {
                let why = match model.contact.stable_step.critical_node {
                    Some(n) if dt_contact < dt_stable_elements && sim.target_dt.is_none() => {
                        format!("contact node {n}")
                    }
                    _ => format!("element {dt_critical_element}"),
                };
                return Err(InputError::new(
                    file,
                    "simulation.dt",
                    format!("{d:e} s exceeds the stable step {scaled_dt:e} s ({why})"),
                ));
            }
            d
        }
        None => scaled_dt,
    };
    model.mass = mass;
    model.dt = dt;
    model.dt_stable = dt_stable;
    model.dt_critical_element = dt_critical_element;
    model.added_mass = added_mass;
    model.scaled_elements = scaled_elements;
    Ok(())
}

/// Accounts for the contact springs in the stable step (see module docs) and, with a
/// target step, raises the mass of the contact nodes that would limit it. `elem_dt` is
/// each element's own critical step (no safety, physical mass) and `elem_scale` its
/// mass-scaling factor; the scaled nodes and added mass reported are the owned nodes'. Returns the contact-limited stable step of the unscaled model
/// (with safety), infinite when no grain can touch another.
#[allow(clippy::too_many_arguments)]
fn account_contact_springs(
    cm: &mut ContactModel,
    tets: &[[u32; 4]],
    elem_dt: &[f64],
    elem_scale: &[f64],
    physical_mass: &[f64],
    mass: &mut [f64],
    safety: f64,
    target_dt: Option<f64>,
    owned_nodes: usize,
) -> f64 {
    let element_omega = elem_dt.iter().map(|d| 2.0 / d).fold(0.0, f64::max);
    let mut report = StableStepReport {
        element_dt: safety * 2.0 / element_omega,
        contact_dt: f64::INFINITY,
        ..Default::default()
    };
    if !cm.grain_contact || cm.node.is_empty() {
        cm.stable_step = report;
        return f64::INFINITY;
    }
    let e_max = cm.e_prime_max;
    // ω_el² per surface node, physical and scaled
    let n = cm.node.len();
    let mut w2_phys = vec![0.0f64; n];
    let mut w2_scaled = vec![0.0f64; n];
    for (e, t) in tets.iter().enumerate() {
        let w2 = (2.0 / elem_dt[e]).powi(2);
        for &node in t {
            let s = cm.surface_index[node as usize];
            if s != NONE {
                let s = s as usize;
                w2_phys[s] = w2_phys[s].max(w2);
                w2_scaled[s] = w2_scaled[s].max(w2 / elem_scale[e]);
            }
        }
    }
    let mut worst = 0.0;
    let omega_t = target_dt.map(|t| 2.0 * safety / t);
    for s in 0..n {
        let node = cm.node[s] as usize;
        let eps = cm.penalty_factor * e_max / cm.node_h[s];
        report.max_penalty = report.max_penalty.max(eps);
        let k = eps * cm.node_area[s];
        let w2 = w2_phys[s] + 2.0 * k / physical_mass[node];
        if w2 > worst {
            worst = w2;
            report.critical_node = Some(node);
        }
        if let Some(wt) = omega_t {
            let wt = wt * ((1.0 + cm.damping * cm.damping).sqrt() - cm.damping);
            let m = mass[node];
            let w2s = w2_scaled[s] + 2.0 * k / m;
            if w2s > wt * wt {
                let needed = (w2_scaled[s] * m + 2.0 * k) / (wt * wt);
                // ghosts get their owner's mass but are reported by their owner
                if node < owned_nodes {
                    report.scaled_nodes += 1;
                    report.added_mass += needed - m;
                }
                mass[node] = needed;
            }
        }
    }
    // central differences with a lagged damper of ratio ζ: Δt ≤ (2/ω)(√(1+ζ²) − ζ)
    let z = cm.damping;
    report.contact_dt = safety * 2.0 / worst.sqrt() * ((1.0 + z * z).sqrt() - z);
    let dt = report.contact_dt;
    cm.stable_step = report;
    dt
}
