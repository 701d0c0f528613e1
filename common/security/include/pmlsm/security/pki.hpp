// The keys, certificates and S/MIME signatures of a keystore, made with OpenSSL's library:
// EC P-256 keys (ECDSA-SHA256, one of the two key types the DDS Security builtin PKI-DH
// plugin accepts), X.509 v3 certificates, and detached S/MIME text signatures (PKCS#7, what
// `openssl smime -sign -text` writes and Fast DDS verifies).
#pragma once

#include <cstdint>
#include <string>

namespace pmlsm::security {

/// A certificate and its private key, both PEM.
struct CertifiedKey {
  std::string cert_pem;
  std::string key_pem;
};

/// Validity relative to now [s]: a negative not_after makes an expired certificate (tests).
struct ValidityWindow {
  std::int64_t not_before_s = 0;
  std::int64_t not_after_s = 365LL * 24 * 3600;
};

/// A self-signed CA (basicConstraints CA:TRUE, keyCertSign and cRLSign, digitalSignature for
/// signing documents) with subject "CN=<common_name>".
/// @throws SecurityError with OpenSSL's reason.
CertifiedKey make_ca(const std::string& common_name, const ValidityWindow& validity);

/// An end-entity certificate "CN=<common_name>" (CA:FALSE, digitalSignature and keyAgreement)
/// issued by `issuer`. @throws SecurityError.
CertifiedKey make_identity(const std::string& common_name, const CertifiedKey& issuer, const ValidityWindow& validity);

/// `document` signed by `signer` as detached S/MIME with a text/plain part.
std::string sign_smime(const std::string& document, const CertifiedKey& signer);

/// The signed text of an S/MIME document when its signature was made by the one certificate
/// `trusted_cert_pem` (certificates carried in the document are ignored: a signer that merely
/// chains to the CA is not the CA); empty with `why` set otherwise.
std::string verify_smime(const std::string& smime, const std::string& trusted_cert_pem, std::string& why);

/// True when `cert_pem` was issued and signed by `ca_cert_pem` and is valid now; `why` says
/// what failed.
bool verify_certificate(const std::string& cert_pem, const std::string& ca_cert_pem, std::string& why);

/// True when the private key belongs to the certificate.
bool key_matches(const std::string& cert_pem, const std::string& key_pem);

/// The certificate's subject in RFC 2253 form ("CN=controller").
std::string subject_name(const std::string& cert_pem);

/// The certificate's validity as "YYYY-MM-DDThh:mm:ss" (UTC), for the permissions document.
void validity_strings(const std::string& cert_pem, std::string& not_before, std::string& not_after);

}  // namespace pmlsm::security
