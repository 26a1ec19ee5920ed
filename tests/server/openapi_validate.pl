#!/usr/bin/perl
# Validates an OpenAPI 3 document (a JSON file) against the OpenAPI 3.0 schema with
# JSON::Validator (Debian: libjson-validator-perl, offline: the schema comes with the
# openapi-specification package). Prints one line per error and "N errors"; exit 1 if any.
use strict;
use warnings;
use JSON::Validator::Schema::OpenAPIv3;

my $schema = JSON::Validator::Schema::OpenAPIv3->new($ARGV[0]);
my @errors = @{ $schema->errors };
print "$_\n" for @errors;
print scalar(@errors), " errors\n";
exit(@errors ? 1 : 0);
