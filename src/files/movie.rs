//! Animated PNG (APNG) movies of turntables, written frame by frame.
//!
//! Decisions:
//! - **APNG through the `png` crate the project already uses**: no new dependency, lossless (a
//!   GIF has 256 colours and would dither the volume's gradients, so frames could not be
//!   compared with the PNG stills), and every browser, `ffmpeg` and most image viewers play it;
//!   a viewer without APNG support shows the first frame. `ffmpeg -i spin.png spin.mp4` makes a
//!   video from it.
//! - **Streamed**: each frame is encoded as soon as it is rendered, so memory does not grow with
//!   the number of frames; the frame count is known up front (the turntable's N).
//! - **Atomic**: written through [`AtomicFile`], so a failure (full disk, a device lost half-way)
//!   leaves no partial movie and any previous file intact. The caller checks the path first
//!   (`write::check_output`: never the input, never a directory).
//! - Provenance tEXt chunks as in every PNG this program writes ([`Provenance`]).

use crate::files::png::{PngError, Provenance};
use crate::files::write::AtomicFile;
use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// The AtomicFile shared between the encoder (which owns its writer) and this module (which
/// commits the file after the encoder is finished).
struct Shared(Rc<RefCell<AtomicFile>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.borrow_mut().flush()
    }
}

/// An APNG being written: [`MovieWriter::push`] each frame, then [`MovieWriter::finish`].
pub struct MovieWriter {
    path: PathBuf,
    file: Rc<RefCell<AtomicFile>>,
    writer: png::Writer<Shared>,
    frames: u32,
    written: u32,
    size: (u32, u32),
}

impl MovieWriter {
    /// Starts a movie of `frames` frames of `width` x `height` RGBA8 at `fps` frames per second,
    /// looping forever.
    pub fn create(
        path: &Path,
        (width, height): (u32, u32),
        frames: u32,
        fps: u16,
        provenance: &Provenance,
    ) -> Result<Self, PngError> {
        let file = Rc::new(RefCell::new(AtomicFile::create(path)?));
        let encode_error = |e: png::EncodingError| encoding(path, &file, e);
        let mut encoder = png::Encoder::new(Shared(Rc::clone(&file)), width, height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        encoder
            .set_animated(frames.max(1), 0)
            .map_err(encode_error)?;
        encoder
            .set_frame_delay(1, fps.max(1))
            .map_err(encode_error)?;
        for (key, value) in provenance.chunks() {
            encoder.add_text_chunk(key, value).map_err(encode_error)?;
        }
        let writer = encoder.write_header().map_err(encode_error)?;
        Ok(MovieWriter {
            path: path.to_path_buf(),
            file,
            writer,
            frames: frames.max(1),
            written: 0,
            size: (width, height),
        })
    }

    /// Encodes the next frame (RGBA8, rows top to bottom, the size given to `create`).
    pub fn push(&mut self, rgba: &[u8]) -> Result<(), PngError> {
        let expected = self.size.0 as usize * self.size.1 as usize * 4;
        if rgba.len() != expected || self.written >= self.frames {
            return Err(PngError::Encode {
                path: self.path.display().to_string(),
                message: format!(
                    "frame {} of {} has {} bytes, expected {expected}",
                    self.written + 1,
                    self.frames,
                    rgba.len()
                ),
            });
        }
        self.writer
            .write_image_data(rgba)
            .map_err(|e| encoding(&self.path, &self.file, e))?;
        self.written += 1;
        Ok(())
    }

    /// Ends the stream and puts the file in place.
    pub fn finish(self) -> Result<(), PngError> {
        let MovieWriter {
            path, file, writer, ..
        } = self;
        writer.finish().map_err(|e| encoding(&path, &file, e))?;
        let file = Rc::try_unwrap(file)
            .map_err(|_| PngError::Encode {
                path: path.display().to_string(),
                message: "the encoder still holds the file".into(),
            })?
            .into_inner();
        Ok(file.commit()?)
    }
}

fn encoding(path: &Path, file: &Rc<RefCell<AtomicFile>>, e: png::EncodingError) -> PngError {
    match e {
        png::EncodingError::IoError(io) => PngError::Output(file.borrow().error(io)),
        other => PngError::Encode {
            path: path.display().to_string(),
            message: other.to_string(),
        },
    }
}
