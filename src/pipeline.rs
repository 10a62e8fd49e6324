use crate::{Mesh, Params, PointSet, Progress, Result};

pub(crate) fn run(_points: &PointSet, _params: &Params, _pool: &rayon::ThreadPool, _progress: Progress<'_>) -> Result<Mesh> {
    Err(crate::Error::Internal("pipeline being written".into()))
}
