//! Every check kind, one line each: adding a kind is a file in `checks/` and a line here.
//! The order is the order error messages list them in.

use super::checks::{
    albedo, algorithm_agreement, bdpt_strategies, chi2, convergence, energy, estimators, furnace,
    half_space, hg, image, lambert, measured, phase, radiance, radiosity_furnace, reciprocity,
    reciprocity_image, reference_convergence, refraction, scale, smooth_limit, transmittance,
    weights,
};
use super::kind::{DynKind, Registered};
use std::marker::PhantomData;

/// The kinds a manifest may name.
pub static KINDS: &[&dyn DynKind] = &[
    &Registered::<half_space::HalfSpace>(PhantomData),
    &Registered::<transmittance::Transmittance>(PhantomData),
    &Registered::<furnace::Furnace>(PhantomData),
    &Registered::<lambert::Lambert>(PhantomData),
    &Registered::<refraction::Refraction>(PhantomData),
    &Registered::<reciprocity::Reciprocity>(PhantomData),
    &Registered::<energy::Energy>(PhantomData),
    &Registered::<albedo::Albedo>(PhantomData),
    &Registered::<smooth_limit::SmoothLimit>(PhantomData),
    &Registered::<hg::Hg>(PhantomData),
    &Registered::<phase::PhaseKind>(PhantomData),
    &Registered::<chi2::Chi2>(PhantomData),
    &Registered::<radiance::RadianceInvariance>(PhantomData),
    &Registered::<estimators::EstimatorAgreement>(PhantomData),
    &Registered::<weights::SampleWeights>(PhantomData),
    &Registered::<scale::ScaleInvariance>(PhantomData),
    &Registered::<image::ImageCompare>(PhantomData),
    &Registered::<measured::Measured>(PhantomData),
    &Registered::<reciprocity_image::ReciprocityImage>(PhantomData),
    &Registered::<convergence::Convergence>(PhantomData),
    &Registered::<radiosity_furnace::RadiosityFurnace>(PhantomData),
    &Registered::<algorithm_agreement::AlgorithmAgreement>(PhantomData),
    &Registered::<reference_convergence::ReferenceConvergence>(PhantomData),
    &Registered::<bdpt_strategies::BdptStrategies>(PhantomData),
];

/// The kind named `name`.
pub fn find(name: &str) -> Option<&'static dyn DynKind> {
    KINDS.iter().copied().find(|k| k.name() == name)
}

/// Every kind's name, in registry order.
pub fn names() -> Vec<&'static str> {
    KINDS.iter().map(|k| k.name()).collect()
}
