//! A bake's backend: the device opened on first use and shared by a batch, the GPU baker or
//! the CPU without one.

use super::*;

/// A bake's device, opened on first use — after the input and options are checked, so that
/// their errors come first — and then shared by every bake of a batch.
pub(crate) struct Device<'a> {
    opened: std::cell::OnceCell<Option<GpuBaker>>,
    open: Box<dyn Fn() -> Result<Option<GpuBaker>> + 'a>,
}

impl<'a> Device<'a> {
    pub(crate) fn new(open: impl Fn() -> Result<Option<GpuBaker>> + 'a) -> Device<'a> {
        Device {
            opened: std::cell::OnceCell::new(),
            open: Box::new(open),
        }
    }

    /// The GPU baker, or `None` for the CPU backend.
    pub(crate) fn get(&self) -> Result<&Option<GpuBaker>> {
        if let Some(baker) = self.opened.get() {
            return Ok(baker);
        }
        let baker = (self.open)()?;
        Ok(self.opened.get_or_init(|| baker))
    }
}

/// The GPU baker for `choice`, or `None` for the CPU backend (saying why when it was not asked
/// for). `bake`, `chart` and `bench` all open their backend here.
pub(crate) fn open_backend(
    choice: DeviceChoice,
    adapter: Option<&str>,
) -> Result<Option<GpuBaker>> {
    let baker = GpuBaker::open(choice, adapter)?;
    if baker.is_none() && choice == DeviceChoice::Auto {
        match device::list_adapters().first() {
            Some(best) => eprintln!(
                "note: only software GPU adapters ({}); the CPU backend is faster on the same \
                 cores and bakes instead (--device gpu forces the adapter)",
                best.name
            ),
            None => eprintln!("note: no GPU adapter found; baking on the CPU backend"),
        }
    }
    Ok(baker)
}

/// Any adapter, software ones included: rasterising a preview is cheap anywhere.
pub(crate) fn open_render_device(adapter: Option<&str>) -> Result<GpuContext> {
    device::open(DeviceChoice::Gpu, adapter)?
        .ok_or_else(|| Error::Gpu("no adapter to render with".into()))
}
