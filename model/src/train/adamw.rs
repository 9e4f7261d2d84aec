//! AdamW (decoupled weight decay) whose moments can be saved and restored, so a resumed run
//! continues exactly where it stopped (candle-nn's optimizer keeps its state private).

use std::collections::HashMap;
use std::path::Path;

use candle_core::{backprop::GradStore, DType, Device, Result, Tensor, Var};

/// Optimizer settings.
#[derive(Clone, Debug)]
pub struct AdamWConfig {
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Added to the root of the second moment.
    pub eps: f64,
    /// Decoupled weight decay per unit learning rate.
    pub weight_decay: f64,
}

impl Default for AdamWConfig {
    /// The paper's betas (0.9, 0.99).
    fn default() -> Self {
        Self {
            beta1: 0.9,
            beta2: 0.99,
            eps: 1e-8,
            weight_decay: 1e-4,
        }
    }
}

/// One variable with its moments.
struct Slot {
    name: String,
    var: Var,
    m: Tensor,
    v: Tensor,
}

/// The optimizer over named variables.
pub struct AdamW {
    slots: Vec<Slot>,
    cfg: AdamWConfig,
    /// Steps taken (bias correction).
    pub step: u64,
}

impl AdamW {
    /// An optimizer over `vars` (name, variable), moments zero.
    pub fn new(mut vars: Vec<(String, Var)>, cfg: AdamWConfig) -> Result<Self> {
        vars.sort_by(|a, b| a.0.cmp(&b.0));
        let slots = vars
            .into_iter()
            .map(|(name, var)| {
                let zeros = var.zeros_like()?;
                Ok(Slot {
                    name,
                    m: zeros.clone(),
                    v: zeros,
                    var,
                })
            })
            .collect::<Result<_>>()?;
        Ok(Self {
            slots,
            cfg,
            step: 0,
        })
    }

    /// The global L2 norm of the gradients; if above `max_norm`, scales them down to it.
    pub fn clip(&self, grads: &mut GradStore, max_norm: f64) -> Result<f64> {
        let mut sq = 0f64;
        for s in &self.slots {
            if let Some(g) = grads.get(s.var.as_tensor()) {
                sq += g
                    .sqr()?
                    .sum_all()?
                    .to_dtype(DType::F64)?
                    .to_scalar::<f64>()?;
            }
        }
        let norm = sq.sqrt();
        if norm.is_finite() && norm > max_norm {
            for s in &self.slots {
                if let Some(g) = grads.remove(s.var.as_tensor()) {
                    grads.insert(s.var.as_tensor(), (g * (max_norm / norm))?);
                }
            }
        }
        Ok(norm)
    }

    /// One update with learning rate `lr`.
    pub fn update(&mut self, grads: &GradStore, lr: f64) -> Result<()> {
        self.step += 1;
        let c = &self.cfg;
        let t = self.step as i32;
        let (bc1, bc2) = (1.0 - c.beta1.powi(t), 1.0 - c.beta2.powi(t));
        for s in &mut self.slots {
            let Some(g) = grads.get(s.var.as_tensor()) else {
                continue;
            };
            // A variable's gradient can carry the op graph of its step (candle detaches the
            // gradients it passes on, not the sums it stores for variables, e.g. a linear
            // layer's weight gradient is a product with the tracked input): detached, so the
            // moments do not chain every step's forward graph together (a leak of about
            // 500 MB per step with the volume branch).
            let g = &g.detach();
            s.m = ((&s.m * c.beta1)? + (g * (1.0 - c.beta1))?)?;
            s.v = ((&s.v * c.beta2)? + (g.sqr()? * (1.0 - c.beta2))?)?;
            let step = ((&s.m / bc1)? / ((&s.v / bc2)?.sqrt()? + c.eps)?)?;
            let decayed = (s.var.as_tensor() * (1.0 - lr * c.weight_decay))?;
            s.var.set(&(decayed - (step * lr)?)?)?;
        }
        Ok(())
    }

    /// One training step's update: clips `grads` to `max_norm`, then updates with `lr`; a
    /// non-finite gradient would poison the weights, so that step is skipped (but counted,
    /// so a seeded sample stream stays the same). Returns the norm before clipping.
    pub fn clip_and_update(
        &mut self,
        grads: &mut GradStore,
        max_norm: f64,
        lr: f64,
    ) -> Result<f64> {
        let norm = self.clip(grads, max_norm)?;
        if norm.is_finite() {
            self.update(grads, lr)?;
        } else {
            self.step += 1;
        }
        Ok(norm)
    }

    /// Writes the moments to a safetensors file (`m.<name>`, `v.<name>`).
    pub fn save(&self, path: &Path) -> Result<()> {
        let mut map = HashMap::new();
        for s in &self.slots {
            map.insert(format!("m.{}", s.name), s.m.clone());
            map.insert(format!("v.{}", s.name), s.v.clone());
        }
        candle_core::safetensors::save(&map, path)
    }

    /// Restores moments written by [`Self::save`] and the step count.
    pub fn load(&mut self, path: &Path, step: u64) -> Result<()> {
        let map = candle_core::safetensors::load(path, &Device::Cpu)?;
        for s in &mut self.slots {
            let get = |k: String| {
                map.get(&k)
                    .cloned()
                    .ok_or_else(|| candle_core::Error::Msg(format!("optimizer state lacks {k}")))
            };
            // Moments live where their variable does (the file is read on the CPU).
            s.m = get(format!("m.{}", s.name))?.to_device(s.m.device())?;
            s.v = get(format!("v.{}", s.name))?.to_device(s.v.device())?;
        }
        self.step = step;
        Ok(())
    }
}
