//! The `lensblur._lensblur` native module: numpy arrays in and out of the lensblur library.
//! A thin layer: every check, conversion and message is the library's (`stack::arrays`,
//! `input`, `camera`, `render::grad`); this file only moves arrays and names things for Python.
use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};
use std::path::PathBuf;

use lensblur::camera::{Aperture, CameraHints, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::input::{read, InputOptions, ResolvedCamera};
use lensblur::job::{CameraValues, JobOptions, LoadedInput, OptionSet, RenderJob};
use lensblur::render::grad::{CameraGradients, Differentiable, Slope};
use lensblur::render::tiler::RenderOptions;
use lensblur::render::{Lens, Method, MethodInput, MethodSettings};
use lensblur::stack::arrays::{ArrayStack, AUTO_LAYERED_GRADIENTS};
use lensblur::stack::{
    grad_output_from_array, read_rgba, stack_from_arrays, stack_to_arrays, DepthKind, WriteOptions,
};
use lensblur::vk::{Context, ContextOptions};
use numpy::{PyArray1, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    lensblur,
    LensblurError,
    PyValueError,
    "An error reported by the lensblur library; the message is its own."
);

/// The library's error as a Python exception, with its causes (an I/O error names the file,
/// its source says what went wrong).
fn to_py(error: lensblur::Error) -> PyErr {
    LensblurError::new_err(error.with_causes())
}

trait OrPy<T> {
    fn or_py(self) -> PyResult<T>;
}

impl<T> OrPy<T> for lensblur::Result<T> {
    fn or_py(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

/// A float32, C-contiguous numpy array's values and shape, borrowed without a copy.
fn f32_array<'py>(name: &str, array: &Bound<'py, PyAny>) -> PyResult<(Bound<'py, PyArrayDyn<f32>>, Vec<usize>)> {
    let untyped = array.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!("{name} must be a numpy array of float32, got {}", array.get_type()))
    })?;
    let float32 = numpy::dtype::<f32>(array.py());
    if !untyped.dtype().is_equiv_to(&float32) {
        return Err(PyTypeError::new_err(format!(
            "{name} must be float32, got {} (convert with .astype(numpy.float32))",
            untyped.dtype()
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(PyTypeError::new_err(format!("{name} must be C-contiguous (numpy.ascontiguousarray makes it so)")));
    }
    let typed = array.cast::<PyArrayDyn<f32>>()?.clone();
    let shape = untyped.shape().to_vec();
    Ok((typed, shape))
}

/// A flat vector as a numpy array of `shape`, handed over without a copy.
fn to_numpy<'py>(py: Python<'py>, values: Vec<f32>, shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    PyArray1::from_vec(py, values).reshape(shape)
}

fn image_to_numpy<'py>(py: Python<'py>, image: Image) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let shape = [image.height, image.width, 4];
    to_numpy(py, image.pixels.into_flattened(), &shape)
}

/// A camera: physical (focal length, f-stop, focus distance, sensor width), or the normalised
/// model (CoC radius in pixels per unit of disparity, and the focus disparity). Each attribute
/// is None where the camera's kind has no such parameter.
#[pyclass(frozen, get_all, module = "lensblur")]
#[derive(Clone)]
struct Camera {
    focal_length_mm: Option<f32>,
    fstop: Option<f32>,
    focus_distance: Option<f32>,
    sensor_width_mm: Option<f32>,
    k_px: Option<f32>,
    focus_disparity: Option<f32>,
}

#[pymethods]
impl Camera {
    /// A thin-lens camera; distances in scene units (metres), focal length and sensor in mm.
    #[staticmethod]
    #[pyo3(signature = (focal_length_mm, fstop, focus_distance, sensor_width_mm = lensblur::input::DEFAULT_SENSOR_WIDTH_MM))]
    fn physical(focal_length_mm: f32, fstop: f32, focus_distance: f32, sensor_width_mm: f32) -> PyResult<Self> {
        PhysicalCamera { focal_length_mm, sensor_width_mm, fstop, focus_distance }.validate().or_py()?;
        Ok(Self {
            focal_length_mm: Some(focal_length_mm),
            fstop: Some(fstop),
            focus_distance: Some(focus_distance),
            sensor_width_mm: Some(sensor_width_mm),
            k_px: None,
            focus_disparity: None,
        })
    }

    /// The normalised model: blur radius `k_px * |d - focus_disparity|` pixels at disparity d.
    #[staticmethod]
    fn normalised(k_px: f32, focus_disparity: f32) -> PyResult<Self> {
        CocModel::new(k_px, focus_disparity).or_py()?;
        let (k_px, focus_disparity) = (Some(k_px), Some(focus_disparity));
        Ok(Self {
            focal_length_mm: None,
            fstop: None,
            focus_distance: None,
            sensor_width_mm: None,
            k_px,
            focus_disparity,
        })
    }

    #[getter]
    fn is_physical(&self) -> bool {
        self.k_px.is_none()
    }

    /// (K in pixels per unit of disparity, focus disparity) for an image `width` pixels wide.
    fn coc(&self, width: usize) -> PyResult<(f32, f32)> {
        let coc = self.resolve(width, Aperture::default())?.lens.coc;
        Ok((coc.k_px, coc.focus_disparity))
    }

    fn __repr__(&self) -> String {
        let show = |v: Option<f32>| v.map_or("None".to_string(), |v| v.to_string());
        if self.is_physical() {
            format!(
                "Camera.physical(focal_length_mm={}, fstop={}, focus_distance={}, sensor_width_mm={})",
                show(self.focal_length_mm),
                show(self.fstop),
                show(self.focus_distance),
                show(self.sensor_width_mm)
            )
        } else {
            format!("Camera.normalised(k_px={}, focus_disparity={})", show(self.k_px), show(self.focus_disparity))
        }
    }
}

impl Camera {
    /// The camera's values, as the library's options name them.
    fn values(&self) -> CameraValues {
        CameraValues {
            focal_length_mm: self.focal_length_mm,
            fstop: self.fstop,
            focus_distance: self.focus_distance,
            sensor_width_mm: self.sensor_width_mm,
            k_px: self.k_px,
            focus_disparity: self.focus_disparity,
        }
    }

    /// The lens for an image `width` pixels wide, by the library's camera policy.
    fn resolve(&self, width: usize, aperture: Aperture) -> PyResult<ResolvedCamera> {
        let request = CameraValues::request(Some(&self.values()), aperture, None).or_py()?;
        request.resolve(width, &CameraHints::default(), &CameraHints::default()).or_py()
    }
}

/// A render's keyword options, parsed by the library ([`JobOptions`]: the parser `lensblur
/// serve` uses too). A name that is no option, or a value of the wrong type, is a `TypeError`;
/// every other check is the library's, with its message.
fn job_options(options: Option<&Bound<'_, PyDict>>, accepted: OptionSet) -> PyResult<JobOptions> {
    let mut object = serde_json::Map::new();
    for (key, value) in options.iter().flat_map(|o| o.iter()) {
        let key: String = key.extract()?;
        let value = to_json(&value).map_err(|e| {
            let message = format!("option {key}: {}", e.value(value.py()));
            if e.is_instance_of::<LensblurError>(value.py()) { LensblurError::new_err(message) } else { PyTypeError::new_err(message) }
        })?;
        object.insert(key, value);
    }
    JobOptions::from_json(object, accepted).map_err(|error| match error {
        lensblur::Error::InvalidParameter { parameter: "options", message } => PyTypeError::new_err(message),
        other => to_py(other),
    })
}

/// An option's value as JSON: None, bools, numbers (numpy scalars too), strings, paths and
/// sequences of them (tuples, lists, 1-D arrays).
fn to_json(value: &Bound<'_, PyAny>) -> PyResult<serde_json::Value> {
    use serde_json::Value;
    if value.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(flag) = value.cast::<pyo3::types::PyBool>() {
        return Ok(Value::Bool(flag.is_true()));
    }
    if let Ok(text) = value.extract::<String>() {
        return Ok(Value::String(text));
    }
    if let Ok(path) = value.extract::<PathBuf>() {
        return Ok(Value::String(path.to_string_lossy().into_owned()));
    }
    // Integers first (numpy integers have __index__), so that counts stay integers.
    if let Ok(integer) = value.extract::<i64>() {
        return Ok(Value::from(integer));
    }
    if let Ok(number) = value.extract::<f64>() {
        // JSON has no NaN or infinity; no option takes one.
        return serde_json::Number::from_f64(number)
            .map(Value::Number)
            .ok_or_else(|| LensblurError::new_err(format!("must be a finite number, got {number}")));
    }
    if let Ok(items) = value.try_iter() {
        return items.map(|item| to_json(&item?)).collect::<PyResult<Vec<_>>>().map(Value::Array);
    }
    Err(PyTypeError::new_err(format!("unsupported type {}", value.get_type().name()?)))
}

/// The render job of `options` through `camera` (None: the file's header), with `method`
/// unless the options name one.
fn render_job(options: &JobOptions, camera: Option<&Camera>, method: Method) -> PyResult<RenderJob> {
    let values = camera.map(Camera::values);
    let spec = options.spec(values.as_ref(), method).or_py()?;
    RenderJob::new(spec).or_py()
}

fn parse_method(name: &str) -> PyResult<Method> {
    name.parse::<Method>().or_py()
}

fn parse_depth_kind(name: &str) -> PyResult<DepthKind> {
    name.parse::<DepthKind>().or_py()
}

/// One device, opened once, with every method's pipelines built on first use and kept.
/// Renders run with the GIL released (other Python threads go on: a data loader, a UI); the
/// caches' locks make one render at a time per Renderer, so calls from several threads queue.
#[pyclass(module = "lensblur")]
struct Renderer {
    // Declared before the context: dropped first, while the device still exists.
    prepared: Mutex<HashMap<&'static str, Box<dyn lensblur::render::Renderer>>>,
    differentiable: Mutex<HashMap<DifferentiableKey, Box<dyn Differentiable>>>,
    context: Option<Context>,
}

/// A method's name and whether its backward is the leaky one.
type DifferentiableKey = (&'static str, bool);

/// A cache's lock; a render that panicked while holding it left the cache consistent (entries
/// are inserted whole), so the poison is ignored.
fn lock<T>(cache: &Mutex<T>) -> MutexGuard<'_, T> {
    cache.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The value cached under `key`, made by `make` on first use (a failure caches nothing).
fn cached<K: std::hash::Hash + Eq, V>(
    cache: &mut HashMap<K, V>,
    key: K,
    make: impl FnOnce() -> lensblur::Result<V>,
) -> lensblur::Result<&mut V> {
    Ok(match cache.entry(key) {
        std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
        std::collections::hash_map::Entry::Vacant(e) => e.insert(make()?),
    })
}

/// The arrays and camera of one call, read by the library.
struct Call {
    input: ArrayStack,
    camera: ResolvedCamera,
    method: Method,
}

impl Call {
    fn new(
        layers: &Bound<'_, PyAny>,
        depth: &Bound<'_, PyAny>,
        camera: &Camera,
        method: &str,
        aperture: &str,
        depth_kind: &str,
    ) -> PyResult<Self> {
        let input = read_arrays(layers, depth, depth_kind)?;
        let camera = camera.resolve(input.stack.width, Aperture::parse(aperture).or_py()?)?;
        Ok(Self { input, camera, method: parse_method(method)? })
    }

    fn lens(&self) -> &Lens {
        &self.camera.lens
    }
}

/// Reads `layers` and `depth` arrays (see `Renderer.render`) with the library's checks.
fn read_arrays(layers: &Bound<'_, PyAny>, depth: &Bound<'_, PyAny>, depth_kind: &str) -> PyResult<ArrayStack> {
    let (layers, layers_shape) = f32_array("layers", layers)?;
    let (depth, depth_shape) = f32_array("depth", depth)?;
    let (layers, depth) = (layers.readonly(), depth.readonly());
    stack_from_arrays(layers.as_slice()?, &layers_shape, depth.as_slice()?, &depth_shape, parse_depth_kind(depth_kind)?)
        .or_py()
}

impl Renderer {
    fn context(&self) -> PyResult<&Context> {
        self.context.as_ref().ok_or_else(|| LensblurError::new_err("this Renderer was closed"))
    }

    /// Runs `job` on `loaded` with the GIL released, on the method's renderer made once per
    /// Renderer (`leaky`: the leaky backward's forward), and cuts the overscan.
    fn render_job(&self, py: Python<'_>, job: &RenderJob, loaded: &LoadedInput, leaky: bool) -> PyResult<Image> {
        let method = job.method();
        let render = |renderer: &dyn lensblur::render::Renderer| -> lensblur::Result<Image> {
            let rendered = job.render_with(renderer, loaded, None)?;
            Ok(job.output(&rendered.image, loaded)?.into_owned())
        };
        if leaky {
            return self.with_differentiable(py, method, true, |d| {
                let forward = |input: MethodInput<'_>, lens: &Lens, _: &RenderOptions, _: &MethodSettings| {
                    d.forward(input.layers()?, lens)
                };
                render(&forward)
            });
        }
        let context = self.context()?;
        py.detach(|| {
            let mut prepared = lock(&self.prepared);
            let renderer = cached(&mut prepared, method.name(), || method.prepare(Some(context)))?;
            render(renderer.as_ref())
        })
        .or_py()
    }

    /// Runs `f` with the method's backward-capable renderer, made on first use, the GIL released.
    fn with_differentiable<T: Send>(
        &self,
        py: Python<'_>,
        method: Method,
        leaky: bool,
        f: impl FnOnce(&dyn Differentiable) -> lensblur::Result<T> + Send,
    ) -> PyResult<T> {
        let context = self.context()?;
        py.detach(|| {
            let slope = if leaky { Slope::Leaky } else { Slope::Exact };
            let mut cache = lock(&self.differentiable);
            let renderer = cached(&mut cache, (method.name(), leaky), || method.differentiable(context, slope))?;
            f(renderer.as_ref())
        })
        .or_py()
    }
}

#[pymethods]
impl Renderer {
    /// Opens a Vulkan device: `device` is an index or a name substring as `lensblur devices`
    /// lists them (default: LENSBLUR_DEVICE, else the first GPU, else lavapipe).
    #[new]
    #[pyo3(signature = (device = None))]
    fn new(device: Option<String>) -> PyResult<Self> {
        let mut options = ContextOptions::from_env();
        if device.is_some() {
            options.device = device;
        }
        Ok(Self {
            prepared: Mutex::default(),
            differentiable: Mutex::default(),
            context: Some(Context::new(&options).or_py()?),
        })
    }

    /// The device's name.
    #[getter]
    fn device(&self) -> PyResult<String> {
        Ok(self.context()?.info().name.clone())
    }

    /// Renders premultiplied RGBA `layers` (L, H, W, 4) float32, front to back, with `depth`
    /// (L, H, W) stored as `depth_kind`; or one image (H, W, 4) with depth (H, W), split into
    /// layers for a layered method. `leaky=True` renders the forward of the leaky backward.
    /// `options` are `lensblur render`'s image-changing flags in snake_case (`render_options()`
    /// lists them), checked by the library as the command line's are. Returns the defocused
    /// premultiplied RGBA, (H, W, 4) float32.
    #[pyo3(signature = (layers, depth, camera, *, depth_kind = "z", leaky = false, **options))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        layers: &Bound<'py, PyAny>,
        depth: &Bound<'py, PyAny>,
        camera: &Camera,
        depth_kind: &str,
        leaky: bool,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let job = render_job(&job_options(options, OptionSet::Render)?, Some(camera), Method::default())?;
        let arrays = read_arrays(layers, depth, depth_kind)?;
        let loaded = job.load_arrays(arrays).or_py()?;
        let image = self.render_job(py, &job, &loaded, leaky)?;
        image_to_numpy(py, image)
    }

    /// Reads `path` as `lensblur render` does (a layered, flat or deep EXR, or a PNG/JPEG with
    /// `depth=` its depth image) and renders it through `camera` (None: the camera in the
    /// file's header; a `Camera` overrides it). `options` are the render options and the file
    /// options (`layers`, `depth`, `depth_kind`, `max_pixels`, `replace_nonfinite`, `merge`,
    /// `max_samples`, `deep_part`, `deep_flatten`). Returns the defocused premultiplied RGBA,
    /// (H, W, 4) float32, the image `lensblur render` writes.
    #[pyo3(signature = (path, camera = None, **options))]
    fn render_file<'py>(
        &self,
        py: Python<'py>,
        path: PathBuf,
        camera: Option<&Camera>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let job = render_job(&job_options(options, OptionSet::File)?, camera, Method::default())?;
        let loaded = py.detach(|| job.load(&path, &CameraHints::default())).or_py()?;
        let image = self.render_job(py, &job, &loaded, false)?;
        image_to_numpy(py, image)
    }

    /// The backward pass: dL/d(inputs) for `grad_output` = dL/d(render) as (H, W, 3) or
    /// (H, W, 4) with a zero alpha gradient. Returns a dict: `layers` (L, H, W, 4) dL/d(premultiplied
    /// RGBA), `depth` (L, H, W) dL/d(depth as stored, through `depth_kind`), and `camera`:
    /// dL/d(k_px, focus_disparity) and, for a physical camera, dL/d(focus_distance, fstop,
    /// focal_length_mm).
    #[pyo3(signature = (layers, depth, camera, grad_output, *, method = "drbokeh", aperture = "disk", depth_kind = "z", leaky = false))]
    #[allow(clippy::too_many_arguments)]
    fn render_backward<'py>(
        &self,
        py: Python<'py>,
        layers: &Bound<'py, PyAny>,
        depth: &Bound<'py, PyAny>,
        camera: &Camera,
        grad_output: &Bound<'py, PyAny>,
        method: &str,
        aperture: &str,
        depth_kind: &str,
        leaky: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let call = Call::new(layers, depth, camera, method, aperture, depth_kind)?;
        if call.input.single_image && call.method.input() == lensblur::render::InputKind::Layers {
            return Err(LensblurError::new_err(format!("{AUTO_LAYERED_GRADIENTS}: pass layers (L, H, W, 4)")));
        }
        let (grad, grad_shape) = f32_array("grad_output", grad_output)?;
        let grad = grad.readonly();
        let (w, h) = (call.input.stack.width, call.input.stack.height);
        let grad = grad_output_from_array(grad.as_slice()?, &grad_shape, w, h).or_py()?;
        let grads =
            self.with_differentiable(py, call.method, leaky, |d| d.backward(&call.input.stack, call.lens(), &grad))?;
        let (d_layers, d_depth) = call.input.gradients(&grads).or_py()?;
        let count = call.input.stack.layers.len();
        let pixel_shape: Vec<usize> = if call.input.single_image { vec![h, w] } else { vec![count, h, w] };
        let rgba_shape: Vec<usize> = pixel_shape.iter().copied().chain([4]).collect();
        let camera = CameraGradients::new(&grads, &call.lens().coc, call.camera.physical.as_ref());
        let camera_dict = PyDict::new(py);
        camera_dict.set_item("k_px", camera.k_px)?;
        camera_dict.set_item("focus_disparity", camera.focus_disparity)?;
        camera_dict.set_item("focus_distance", camera.focus_distance)?;
        camera_dict.set_item("fstop", camera.fstop)?;
        camera_dict.set_item("focal_length_mm", camera.focal_length_mm)?;
        let out = PyDict::new(py);
        out.set_item("layers", to_numpy(py, d_layers, &rgba_shape)?)?;
        out.set_item("depth", to_numpy(py, d_depth, &pixel_shape)?)?;
        out.set_item("camera", camera_dict)?;
        Ok(out)
    }

    /// Releases the device now, reporting any validation error (`LENSBLUR_VALIDATION=1`).
    fn close(&mut self) -> PyResult<()> {
        lock(&self.prepared).clear();
        lock(&self.differentiable).clear();
        match self.context.take() {
            Some(context) => context.finish().or_py(),
            None => Ok(()),
        }
    }
}

/// A resident renderer over one stack, for focus pulled interactively: the device opened once,
/// the method's pipelines prepared once, the arrays read once; each `render(camera, **options)`
/// re-layers a flat image only when the camera changes its cut. Renders equal `lensblur.render`
/// of the same arrays and options. A context manager (`with lensblur.Session(...) as s:`).
#[pyclass(module = "lensblur")]
struct Session {
    session: Mutex<Option<lensblur::session::Session>>,
    method: Method,
    last: Mutex<lensblur::session::SessionRender>,
}

#[pymethods]
impl Session {
    /// `layers` (L, H, W, 4) or one image (H, W, 4) with `depth` as in `render`; `method` the
    /// default of every render (an option `method=` overrides it); `device` as in `Renderer`.
    #[new]
    #[pyo3(signature = (layers, depth, *, method = "drbokeh", device = None, depth_kind = "z"))]
    fn new(layers: &Bound<'_, PyAny>, depth: &Bound<'_, PyAny>, method: &str, device: Option<String>, depth_kind: &str) -> PyResult<Self> {
        let method = parse_method(method)?;
        let input = lensblur::input::ReadInput::from_arrays(read_arrays(layers, depth, depth_kind)?);
        let mut options = ContextOptions::from_env();
        if device.is_some() {
            options.device = device;
        }
        let context = Context::new(&options).or_py()?;
        Ok(Self {
            session: Mutex::new(Some(lensblur::session::Session::new(Some(std::sync::Arc::new(context)), input))),
            method,
            last: Mutex::default(),
        })
    }

    /// Renders the stack through `camera` with the keyword `options` (`RENDER_OPTIONS`, as
    /// `lensblur.render` takes them); returns the defocused premultiplied RGBA, (H, W, 4).
    #[pyo3(signature = (camera, **options))]
    fn render<'py>(&self, py: Python<'py>, camera: &Camera, options: Option<&Bound<'py, PyDict>>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let job = render_job(&job_options(options, OptionSet::Render)?, Some(camera), self.method)?;
        let (image, stats) = py
            .detach(|| {
                let mut guard = lock(&self.session);
                match guard.as_mut() {
                    Some(session) => session.render(&job).map_err(to_py),
                    None => Err(LensblurError::new_err("this Session was closed")),
                }
            })?;
        *lock(&self.last) = stats;
        image_to_numpy(py, image)
    }

    /// What the last render did: `relayered` (the camera changed the layering), `prepared` (the
    /// method's first render where it ran), `cpu` (it ran on the CPU: no device, or a small
    /// frame through a disk on a CPU device, as a one-shot render would), and `layering_ms`,
    /// `render_ms`, `total_ms`.
    #[getter]
    fn last_render<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let stats = *lock(&self.last);
        let out = PyDict::new(py);
        out.set_item("relayered", stats.relayered)?;
        out.set_item("prepared", stats.prepared)?;
        out.set_item("cpu", stats.cpu)?;
        out.set_item("layering_ms", stats.layering_ms)?;
        out.set_item("render_ms", stats.render_ms)?;
        out.set_item("total_ms", stats.total_ms)?;
        Ok(out)
    }

    /// Releases the device now, reporting any validation error (`LENSBLUR_VALIDATION=1`).
    fn close(&self) -> PyResult<()> {
        match lock(&self.session).take() {
            Some(session) => session.close().or_py(),
            None => Ok(()),
        }
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_exc))]
    fn __exit__(&self, _exc: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        self.close()?;
        Ok(false)
    }
}

/// Reads a layered EXR (any naming convention lensblur reads) or a PNG/JPEG with `depth_image`.
/// Returns a dict: `layers` (L, H, W, 4) premultiplied RGBA, `depth` (L, H, W) as `depth_kind`
/// (filled under transparent pixels, as the renderer reads it), `names`, `depth_kind`, and
/// `camera` from the EXR header (None when it does not hold a whole physical camera).
#[pyfunction]
#[pyo3(signature = (path, *, layers = None, depth_kind = None, depth_image = None))]
fn read_stack<'py>(
    py: Python<'py>,
    path: PathBuf,
    layers: Option<Vec<String>>,
    depth_kind: Option<&str>,
    depth_image: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let options = InputOptions {
        layers,
        depth_kind: depth_kind.map(parse_depth_kind).transpose()?,
        depth_image,
        ..InputOptions::default()
    };
    let (stack, info, kind, _warnings) = py.detach(|| read(&path, &options)).or_py()?;
    let (w, h, count) = (stack.width, stack.height, stack.layers.len());
    let names: Vec<String> = stack.layers.iter().map(|l| l.name.clone()).collect();
    let (rgba, depth) = stack_to_arrays(stack, kind);
    let hints = info.as_ref().map(|i| CameraHints::from_attributes(&i.camera)).unwrap_or_default();
    let camera = match (hints.focal_length_mm, hints.fstop, hints.focus_distance) {
        (Some(f), Some(n), Some(d)) => {
            let sensor = hints.sensor_width_mm.unwrap_or(lensblur::input::DEFAULT_SENSOR_WIDTH_MM);
            Some(Camera::physical(f, n, d, sensor)?)
        }
        _ => None,
    };
    let out = PyDict::new(py);
    out.set_item("layers", to_numpy(py, rgba, &[count, h, w, 4])?)?;
    out.set_item("depth", to_numpy(py, depth, &[count, h, w])?)?;
    out.set_item("names", names)?;
    out.set_item("depth_kind", kind.name())?;
    out.set_item("camera", camera)?;
    Ok(out)
}

/// Reads an EXR's RGBA (its first colour layer, or `layer`) as (H, W, 4) float32.
#[pyfunction]
#[pyo3(signature = (path, *, layer = None))]
fn read_image<'py>(py: Python<'py>, path: PathBuf, layer: Option<&str>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let image = py.detach(|| read_rgba(&path, layer, lensblur::stack::DEFAULT_MAX_PIXELS)).or_py()?;
    image_to_numpy(py, image)
}

/// Writes premultiplied RGBA (H, W, 4) float32 as an EXR (32-bit float, ZIP), atomically.
#[pyfunction]
fn write_image(path: PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let (array, shape) = f32_array("image", image)?;
    let [height, width, 4] = shape[..] else {
        return Err(LensblurError::new_err(format!("image must have shape (H, W, 4); got shape {shape:?}")));
    };
    let array = array.readonly();
    let pixels: Vec<[f32; 4]> = bytemuck::cast_slice(array.as_slice()?).to_vec();
    lensblur::stack::OutputFormat::for_output(&path, "path", lensblur::stack::OutputFormat::EXR).or_py()?;
    let options = WriteOptions { sample_type: lensblur::stack::SampleType::Float, ..WriteOptions::default() };
    lensblur::stack::write_image(&path, &Image { width, height, pixels }, &options).or_py()
}

/// Ray-traces a built-in scene (`lensblur raytrace --list`): its true layers, their planar
/// depth, the thin-lens defocused image and the camera. A dict: `layers` (L, H, W, 4), `depth`
/// (L, H, W) planar Z, `defocused` and `pinhole` (H, W, 4), `camera`.
#[pyfunction]
#[pyo3(signature = (scene = "branches", *, scale = 1.0, samples = 8))]
fn raytrace<'py>(py: Python<'py>, scene: &str, scale: f32, samples: usize) -> PyResult<Bound<'py, PyDict>> {
    use lensblur::raytrace::{builtin_scene, render_ground_truth, TraceOptions};
    let scene = builtin_scene(scene).or_py()?;
    let options = TraceOptions { samples_per_axis: samples, scale, ..TraceOptions::default() };
    let truth = py.detach(|| render_ground_truth(&scene, &options)).or_py()?;
    let (w, h, count) = (truth.layers.width, truth.layers.height, truth.layers.layers.len());
    let (rgba, depth) = stack_to_arrays(truth.layers, DepthKind::Z);
    let c = truth.camera;
    let out = PyDict::new(py);
    out.set_item("layers", to_numpy(py, rgba, &[count, h, w, 4])?)?;
    out.set_item("depth", to_numpy(py, depth, &[count, h, w])?)?;
    out.set_item("defocused", image_to_numpy(py, truth.defocused)?)?;
    out.set_item("pinhole", image_to_numpy(py, truth.pinhole)?)?;
    out.set_item("camera", Camera::physical(c.focal_length_mm, c.fstop, c.focus_distance, c.sensor_width_mm)?)?;
    Ok(out)
}

/// The names of the rendering methods, and of those with a backward pass.
#[pyfunction]
fn methods() -> (Vec<&'static str>, Vec<&'static str>) {
    (Method::ALL.iter().map(|m| m.name()).collect(), Method::differentiable_names())
}

/// The keyword options of a render (`lensblur render`'s image-changing flags in snake_case),
/// and the further ones of a render read from a file.
#[pyfunction]
fn render_options() -> (Vec<&'static str>, Vec<&'static str>) {
    (lensblur::job::RENDER_OPTIONS.to_vec(), lensblur::job::FILE_OPTIONS.to_vec())
}

#[pymodule]
fn _lensblur(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Camera>()?;
    m.add_class::<Renderer>()?;
    m.add_class::<Session>()?;
    m.add("LensblurError", m.py().get_type::<LensblurError>())?;
    m.add_function(wrap_pyfunction!(read_stack, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(write_image, m)?)?;
    m.add_function(wrap_pyfunction!(raytrace, m)?)?;
    m.add_function(wrap_pyfunction!(methods, m)?)?;
    m.add_function(wrap_pyfunction!(render_options, m)?)?;
    Ok(())
}
