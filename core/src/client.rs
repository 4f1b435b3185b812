//! The client side of the coordinator's API, written once for the `coordinator` CLI and
//! the worker daemon: the endpoint (TLS when the URL is `https://`, trusting `--tls-ca`),
//! the access token on every call, the chunk size of checkpoint transfers, and a
//! checkpoint download checked against its sha256.

use crate::pb;
use crate::{bearer, AUTH_HEADER};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::time::Duration;
use tonic::metadata::{Ascii, MetadataValue};
use tonic::transport::{Certificate, ClientTlsConfig, Endpoint};
use tonic::Status;

/// Bytes per message of a checkpoint upload or download.
pub const CHUNK: usize = 256 * 1024;

/// Largest message a client accepts (a download chunk, a sweep with its cells).
pub const MAX_MESSAGE: usize = 64 << 20;

/// The endpoint of the coordinator at `url`: TLS for `https://` (trusting the PEM
/// certificate in `ca` when given, else the system roots). The error says which input
/// was wrong.
pub fn endpoint(url: &str, ca: Option<&Path>) -> Result<Endpoint, String> {
    let mut ep = Endpoint::from_shared(url.to_string())
        .map_err(|e| format!("bad coordinator url {url:?}: {e}"))?
        .connect_timeout(Duration::from_secs(5))
        .tcp_nodelay(true);
    if url.starts_with("https://") {
        let mut tls = ClientTlsConfig::new();
        if let Some(ca) = ca {
            let pem =
                std::fs::read(ca).map_err(|e| format!("read --tls-ca {}: {e}", ca.display()))?;
            tls = tls.ca_certificate(Certificate::from_pem(pem));
        }
        ep = ep
            .tls_config(tls)
            .map_err(|e| format!("tls settings for {url:?}: {e}"))?;
    }
    Ok(ep)
}

/// Adds the access token (if any) to every call.
#[derive(Clone, Debug, Default)]
pub struct Auth(Option<MetadataValue<Ascii>>);

impl Auth {
    /// The interceptor for `token`; refuses a token that cannot be sent as metadata.
    pub fn new(token: Option<&str>) -> Result<Self, String> {
        match token {
            None => Ok(Auth(None)),
            Some(t) => bearer(t)
                .parse()
                .map(|v| Auth(Some(v)))
                .map_err(|_| "the token has characters not allowed in metadata".to_string()),
        }
    }
}

impl tonic::service::Interceptor for Auth {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, Status> {
        if let Some(t) = &self.0 {
            req.metadata_mut().insert(AUTH_HEADER, t.clone());
        }
        Ok(req)
    }
}

/// Why a checkpoint download gave no file.
#[derive(Debug)]
pub enum DownloadError {
    /// The call failed.
    Call(Status),
    /// The bytes arrived but do not hash to what was asked for (retry).
    Corrupt {
        /// The sha256 of what arrived.
        got: String,
    },
}

/// Reads a checkpoint download to the end and checks it against `sha256`.
pub async fn collect_checkpoint(
    stream: &mut tonic::Streaming<pb::CheckpointChunk>,
    sha256: &str,
    size_hint: u64,
) -> Result<Vec<u8>, DownloadError> {
    let mut bytes = Vec::with_capacity(size_hint.min(1 << 30) as usize);
    while let Some(chunk) = stream.message().await.map_err(DownloadError::Call)? {
        bytes.extend_from_slice(&chunk.data);
    }
    let got = hex::encode(Sha256::digest(&bytes));
    if got != sha256 {
        return Err(DownloadError::Corrupt { got });
    }
    Ok(bytes)
}

/// The messages of one upload: the header, then the file in [`CHUNK`]-byte pieces.
pub fn upload_messages(header: pb::UploadHeader, bytes: &[u8]) -> Vec<pb::UploadCheckpointRequest> {
    use pb::upload_checkpoint_request::Part;
    let mut msgs = vec![pb::UploadCheckpointRequest {
        part: Some(Part::Header(header)),
    }];
    msgs.extend(bytes.chunks(CHUNK).map(|c| pb::UploadCheckpointRequest {
        part: Some(Part::Chunk(pb::CheckpointChunk { data: c.to_vec() })),
    }));
    msgs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uploads_are_a_header_then_chunks() {
        let bytes = vec![7u8; CHUNK * 2 + 5];
        let m = upload_messages(pb::UploadHeader::default(), &bytes);
        assert_eq!(m.len(), 4);
        assert!(matches!(
            m[0].part,
            Some(pb::upload_checkpoint_request::Part::Header(_))
        ));
    }

    #[test]
    fn bad_inputs_are_named() {
        assert!(endpoint("not a url", None)
            .unwrap_err()
            .contains("not a url"));
        assert!(
            endpoint("https://h:1", Some(Path::new("/nonexistent/ca.pem")))
                .unwrap_err()
                .contains("--tls-ca /nonexistent/ca.pem")
        );
        assert!(Auth::new(Some("bad\ntoken")).is_err());
        assert!(Auth::new(Some("good")).is_ok());
    }
}
