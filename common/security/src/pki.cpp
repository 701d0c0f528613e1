#include "pmlsm/security/pki.hpp"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <ctime>
#include <memory>

#include "pmlsm/security/policy.hpp"

namespace pmlsm::security {
namespace {

template <typename T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using Bio = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;
using Key = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using Cert = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using Pkcs7 = std::unique_ptr<PKCS7, Deleter<PKCS7, PKCS7_free>>;
using Store = std::unique_ptr<X509_STORE, Deleter<X509_STORE, X509_STORE_free>>;
using StoreCtx = std::unique_ptr<X509_STORE_CTX, Deleter<X509_STORE_CTX, X509_STORE_CTX_free>>;
using Ext = std::unique_ptr<X509_EXTENSION, Deleter<X509_EXTENSION, X509_EXTENSION_free>>;

void free_cert_stack(STACK_OF(X509) * s) { sk_X509_free(s); }
using CertStack = std::unique_ptr<STACK_OF(X509), Deleter<STACK_OF(X509), free_cert_stack>>;

/// OpenSSL's queued errors as one line (and the queue emptied).
std::string openssl_errors() {
  std::string out;
  while (const unsigned long e = ERR_get_error()) {
    char buf[256];
    ERR_error_string_n(e, buf, sizeof buf);
    out += (out.empty() ? "" : "; ") + std::string(buf);
  }
  return out.empty() ? "no reason given" : out;
}

[[noreturn]] void fail(const std::string& what) { throw SecurityError(what + ": " + openssl_errors()); }

Bio memory_bio(const std::string& text) {
  Bio bio(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  if (!bio) fail("cannot allocate a memory BIO");
  return bio;
}

std::string bio_text(BIO* bio) {
  char* data = nullptr;
  const long size = BIO_get_mem_data(bio, &data);
  return size > 0 ? std::string(data, static_cast<std::size_t>(size)) : std::string();
}

Cert read_cert(const std::string& pem) {
  auto bio = memory_bio(pem);
  Cert cert(PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr));
  if (!cert) fail("not a PEM certificate");
  return cert;
}

Key read_key(const std::string& pem) {
  auto bio = memory_bio(pem);
  Key key(PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr));
  if (!key) fail("not a PEM private key");
  return key;
}

Key new_key() {
  Key key(EVP_EC_gen("P-256"));
  if (!key) fail("cannot generate an EC P-256 key");
  return key;
}

void add_extension(X509* cert, X509* issuer, int nid, const char* value) {
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, issuer, cert, nullptr, nullptr, 0);
  Ext ext(X509V3_EXT_conf_nid(nullptr, &ctx, nid, value));
  if (!ext || X509_add_ext(cert, ext.get(), -1) != 1) fail(std::string("cannot add extension ") + value);
}

/// A certificate for `key` named CN=common_name, signed by `issuer_key` (self-signed when
/// issuer is null).
Cert new_cert(const std::string& common_name, EVP_PKEY* key, X509* issuer, EVP_PKEY* issuer_key,
              const ValidityWindow& validity, bool is_ca) {
  Cert cert(X509_new());
  if (!cert) fail("cannot allocate a certificate");
  X509_set_version(cert.get(), 2);  // v3
  // A random positive 63-bit serial: unique per CA without keeping a counter.
  unsigned char serial_bytes[8];
  if (RAND_bytes(serial_bytes, sizeof serial_bytes) != 1) fail("no random bytes for a serial number");
  serial_bytes[0] &= 0x7F;
  std::uint64_t serial = 0;
  for (const auto b : serial_bytes) serial = (serial << 8) | b;
  ASN1_INTEGER_set_uint64(X509_get_serialNumber(cert.get()), serial == 0 ? 1 : serial);
  X509_gmtime_adj(X509_getm_notBefore(cert.get()), static_cast<long>(validity.not_before_s));
  X509_gmtime_adj(X509_getm_notAfter(cert.get()), static_cast<long>(validity.not_after_s));
  X509_set_pubkey(cert.get(), key);
  X509_NAME* name = X509_get_subject_name(cert.get());
  if (X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_UTF8, reinterpret_cast<const unsigned char*>(common_name.c_str()),
                                 -1, -1, 0) != 1) {
    fail("cannot set the subject CN=" + common_name);
  }
  X509* signer_cert = issuer != nullptr ? issuer : cert.get();
  X509_set_issuer_name(cert.get(), X509_get_subject_name(signer_cert));
  add_extension(cert.get(), signer_cert, NID_basic_constraints, is_ca ? "critical,CA:TRUE" : "critical,CA:FALSE");
  add_extension(cert.get(), signer_cert, NID_key_usage,
                is_ca ? "critical,keyCertSign,cRLSign,digitalSignature" : "critical,digitalSignature,keyAgreement");
  add_extension(cert.get(), signer_cert, NID_subject_key_identifier, "hash");
  if (X509_sign(cert.get(), issuer_key != nullptr ? issuer_key : key, EVP_sha256()) <= 0) {
    fail("cannot sign the certificate CN=" + common_name);
  }
  return cert;
}

CertifiedKey to_pem(X509* cert, EVP_PKEY* key) {
  Bio cert_bio(BIO_new(BIO_s_mem()));
  Bio key_bio(BIO_new(BIO_s_mem()));
  if (!cert_bio || !key_bio || PEM_write_bio_X509(cert_bio.get(), cert) != 1 ||
      PEM_write_bio_PrivateKey(key_bio.get(), key, nullptr, nullptr, 0, nullptr, nullptr) != 1) {
    fail("cannot write PEM");
  }
  return CertifiedKey{bio_text(cert_bio.get()), bio_text(key_bio.get())};
}

std::string asn1_time_text(const ASN1_TIME* t) {
  struct tm tm {};
  if (ASN1_TIME_to_tm(t, &tm) != 1) fail("unreadable certificate time");
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  return buf;
}

}  // namespace

CertifiedKey make_ca(const std::string& common_name, const ValidityWindow& validity) {
  auto key = new_key();
  auto cert = new_cert(common_name, key.get(), nullptr, nullptr, validity, true);
  return to_pem(cert.get(), key.get());
}

CertifiedKey make_identity(const std::string& common_name, const CertifiedKey& issuer, const ValidityWindow& validity) {
  auto issuer_cert = read_cert(issuer.cert_pem);
  auto issuer_key = read_key(issuer.key_pem);
  auto key = new_key();
  auto cert = new_cert(common_name, key.get(), issuer_cert.get(), issuer_key.get(), validity, false);
  return to_pem(cert.get(), key.get());
}

std::string sign_smime(const std::string& document, const CertifiedKey& signer) {
  auto cert = read_cert(signer.cert_pem);
  auto key = read_key(signer.key_pem);
  auto in = memory_bio(document);
  // As `openssl smime -sign -text`: the document as a text/plain MIME part, signature detached.
  const int flags = PKCS7_DETACHED | PKCS7_TEXT | PKCS7_STREAM;
  Pkcs7 p7(PKCS7_sign(cert.get(), key.get(), nullptr, in.get(), flags));
  if (!p7) fail("cannot sign the document");
  Bio out(BIO_new(BIO_s_mem()));
  auto again = memory_bio(document);
  if (!out || SMIME_write_PKCS7(out.get(), p7.get(), again.get(), flags) != 1) fail("cannot write S/MIME");
  return bio_text(out.get());
}

std::string verify_smime(const std::string& smime, const std::string& trusted_cert_pem, std::string& why) {
  try {
    auto in = memory_bio(smime);
    BIO* content_raw = nullptr;
    Pkcs7 p7(SMIME_read_PKCS7(in.get(), &content_raw));
    Bio content(content_raw);
    if (!p7) {
      why = "not an S/MIME signed document: " + openssl_errors();
      return {};
    }
    auto trusted = read_cert(trusted_cert_pem);
    CertStack signers(sk_X509_new_null());
    if (!signers || sk_X509_push(signers.get(), trusted.get()) <= 0) fail("cannot allocate a certificate stack");
    Bio out(BIO_new(BIO_s_mem()));
    // NOINTERN: only the given certificate may be the signer (CVE-2023-24010: verifying against
    // a store accepts any signer that chains to the CA, e.g. a participant's own identity);
    // NOVERIFY: that certificate is trusted as it is, not chain-verified.
    if (PKCS7_verify(p7.get(), signers.get(), nullptr, content.get(), out.get(),
                     PKCS7_TEXT | PKCS7_NOINTERN | PKCS7_NOVERIFY) != 1) {
      why = "signature does not verify against the given certificate: " + openssl_errors();
      return {};
    }
    return bio_text(out.get());
  } catch (const SecurityError& e) {
    why = e.what();
    return {};
  }
}

bool verify_certificate(const std::string& cert_pem, const std::string& ca_cert_pem, std::string& why) {
  try {
    auto cert = read_cert(cert_pem);
    auto ca = read_cert(ca_cert_pem);
    Store store(X509_STORE_new());
    StoreCtx ctx(X509_STORE_CTX_new());
    if (!store || !ctx || X509_STORE_add_cert(store.get(), ca.get()) != 1 ||
        X509_STORE_CTX_init(ctx.get(), store.get(), cert.get(), nullptr) != 1) {
      fail("cannot set up certificate verification");
    }
    if (X509_verify_cert(ctx.get()) != 1) {
      why = X509_verify_cert_error_string(X509_STORE_CTX_get_error(ctx.get()));
      return false;
    }
    return true;
  } catch (const SecurityError& e) {
    why = e.what();
    return false;
  }
}

bool key_matches(const std::string& cert_pem, const std::string& key_pem) {
  try {
    auto cert = read_cert(cert_pem);
    auto key = read_key(key_pem);
    return X509_check_private_key(cert.get(), key.get()) == 1;
  } catch (const SecurityError&) {
    return false;
  }
}

std::string subject_name(const std::string& cert_pem) {
  auto cert = read_cert(cert_pem);
  Bio out(BIO_new(BIO_s_mem()));
  if (!out || X509_NAME_print_ex(out.get(), X509_get_subject_name(cert.get()), 0, XN_FLAG_RFC2253) < 0) {
    fail("cannot print the subject");
  }
  return bio_text(out.get());
}

void validity_strings(const std::string& cert_pem, std::string& not_before, std::string& not_after) {
  auto cert = read_cert(cert_pem);
  not_before = asn1_time_text(X509_get0_notBefore(cert.get()));
  not_after = asn1_time_text(X509_get0_notAfter(cert.get()));
}

}  // namespace pmlsm::security
