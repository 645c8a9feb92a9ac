/*---------------------------------------------------------------------------*\
    vfe: void fraction of CFD cells from DEM particles
\*---------------------------------------------------------------------------*/

#include "vfeVoidFraction.H"
#include "dumpSeries.H"

#include "addToRunTimeSelectionTable.H"
#include "labelIOList.H"
#include "processorPolyPatch.H"
#include "processorCyclicPolyPatch.H"
#include "zeroGradientFvPatchFields.H"

#include <vfe/vfe.h>
#include <vfe/vfe_mpi.h>

#include <cmath>
#include <cstdlib>
#include <stdexcept>

// * * * * * * * * * * * * * * Static Data Members * * * * * * * * * * * * * //

namespace Foam
{
namespace functionObjects
{
    defineTypeNameAndDebug(vfeVoidFraction, 0);
    addToRunTimeSelectionTable(functionObject, vfeVoidFraction, dictionary);
}
}


// * * * * * * * * * * * * * * * Local Functions * * * * * * * * * * * * * * //

namespace
{

//- A polyMesh in vfe's 64-bit layout: OpenFOAM's labels may be 32-bit, so this
//  is the one copy of the mesh (the engine keeps its own).
struct meshArrays
{
    std::vector<double> points;
    std::vector<int64_t> offsets;
    std::vector<int64_t> facePoints;
    std::vector<int64_t> owner;
    std::vector<int64_t> neighbour;

    explicit meshArrays(const Foam::polyMesh& mesh)
    {
        const Foam::pointField& pts = mesh.points();
        const Foam::faceList& faces = mesh.faces();
        points.resize(3*pts.size());
        forAll(pts, i)
        {
            for (Foam::direction d = 0; d < 3; ++d) points[3*i + d] = pts[i][d];
        }
        offsets.assign(faces.size() + 1, 0);
        forAll(faces, f) offsets[f + 1] = offsets[f] + faces[f].size();
        facePoints.resize(offsets.back());
        forAll(faces, f)
        {
            forAll(faces[f], k) facePoints[offsets[f] + k] = faces[f][k];
        }
        owner.assign(mesh.faceOwner().begin(), mesh.faceOwner().end());
        neighbour.assign(mesh.faceNeighbour().begin(), mesh.faceNeighbour().end());
    }
};

//- decomposePar's addressing file of the processor mesh (constant/polyMesh),
//  as 64-bit ids; its length must be the mesh's count of that entity.
std::vector<int64_t> procAddressing
(
    const Foam::polyMesh& mesh,
    const Foam::word& name,
    const Foam::label expected
)
{
    const Foam::labelIOList ids
    (
        Foam::IOobject
        (
            name,
            mesh.facesInstance(),
            mesh.meshSubDir,
            mesh,
            Foam::IOobject::MUST_READ,
            Foam::IOobject::NO_WRITE,
            false
        )
    );
    if (ids.size() != expected)
    {
        FatalErrorInFunction
            << ids.objectPath() << " has " << ids.size() << " entries, the"
            << " processor mesh " << expected << ": decompose the case again"
            << " (decomposePar -force); a mesh whose topology changes in a"
            << " parallel run is not supported" << Foam::nl
            << Foam::exit(Foam::FatalError);
    }
    return std::vector<int64_t>(ids.begin(), ids.end());
}

} // End anonymous namespace


// * * * * * * * * * * * * Private Member Functions  * * * * * * * * * * * * //

void Foam::functionObjects::vfeVoidFraction::vfeFailed(const char* call) const
{
    FatalErrorInFunction
        << call << " failed: " << vfe_last_error(engine_) << nl
        << exit(FatalError);
    std::abort();   // not reached: exit(FatalError) ends the run
}


void Foam::functionObjects::vfeVoidFraction::createEngine()
{
    const meshArrays m(mesh_);
    if (!Pstream::parRun())
    {
        vfe_engine* e = nullptr;
        if
        (
            vfe_create_polymesh_arrays
            (
                mesh_.nPoints(), m.points.data(), mesh_.nFaces(),
                m.offsets.data(), m.facePoints.data(), m.owner.data(),
                mesh_.nInternalFaces(), m.neighbour.data(), &e
            ) != VFE_OK
        )
        {
            vfeFailed("vfe_create_polymesh_arrays");
        }
        engine_ = e;
        return;
    }

    // The processor mesh with the undecomposed mesh's ids of its points, faces
    // and cells (decomposePar's addressing; faces on a processor patch are
    // signed by their orientation), which is how the ranks match their shared
    // faces and points. Cyclic transforms are not applied by libvfe_mpi.
    const std::vector<int64_t> pointIds =
        procAddressing(mesh_, "pointProcAddressing", mesh_.nPoints());
    const std::vector<int64_t> faceIds =
        procAddressing(mesh_, "faceProcAddressing", mesh_.nFaces());
    const std::vector<int64_t> cellIds =
        procAddressing(mesh_, "cellProcAddressing", mesh_.nCells());
    std::vector<int64_t> coupled;
    for (const polyPatch& pp : mesh_.boundaryMesh())
    {
        if (isA<processorCyclicPolyPatch>(pp))
        {
            FatalErrorInFunction
                << "patch " << pp.name() << " is a processorCyclic patch;"
                << " vfe in parallel does not apply cyclic transforms: run"
                << " without -parallel or without cyclic patches"
                << nl << exit(FatalError);
        }
        if (isA<processorPolyPatch>(pp))
        {
            for (label f = pp.start(); f < pp.start() + pp.size(); ++f)
            {
                coupled.push_back(f);
            }
        }
    }

    vfe_mpi_polymesh pm = {};
    pm.n_points = mesh_.nPoints();
    pm.points = m.points.data();
    pm.point_ids = pointIds.data();
    pm.n_faces = mesh_.nFaces();
    pm.face_offsets = m.offsets.data();
    pm.face_points = m.facePoints.data();
    pm.owner = m.owner.data();
    pm.n_internal_faces = mesh_.nInternalFaces();
    pm.neighbour = m.neighbour.data();
    pm.face_ids = faceIds.data();
    pm.cell_ids = cellIds.data();
    pm.n_coupled_faces = int64_t(coupled.size());
    pm.coupled_faces = coupled.data();

    // OpenFOAM's world communicator is MPI_COMM_WORLD (UPstream, v1912); the
    // engine duplicates it, so its messages never meet OpenFOAM's.
    vfe_engine* e = nullptr;
    if (vfe_mpi_create_polymesh_arrays(MPI_COMM_WORLD, &pm, &e) != VFE_OK)
    {
        vfeFailed("vfe_mpi_create_polymesh_arrays");
    }
    engine_ = e;
}


void Foam::functionObjects::vfeVoidFraction::configureEngine()
{
    std::string opts = options_;
    if (writeUs_) opts += " weights=1";
    if (vfe_configure(engine_, opts.c_str()) != VFE_OK)
    {
        vfeFailed("vfe_configure");
    }
}


std::vector<std::int64_t> Foam::functionObjects::vfeVoidFraction::ownRows
(
    const std::vector<double>& table,
    const std::int64_t n,
    const int nc,
    const int x,
    const double* radii,
    const std::int64_t radiiStride
) const
{
    std::vector<std::int64_t> rows;
    if (!Pstream::parRun())
    {
        rows.resize(n);
        for (std::int64_t p = 0; p < n; ++p) rows[p] = p;
        return rows;
    }
    // Every rank has read the whole frame; each hands the rows of its share to
    // the ranks owning their centres' cells (libvfe_mpi's particle contract),
    // the row number standing for the particle, so each rank ends with its own
    // rows in increasing order.
    const std::int64_t nProcs = Pstream::nProcs(), me = Pstream::myProcNo();
    const std::int64_t lo = n*me/nProcs, hi = n*(me + 1)/nProcs;
    std::vector<double> centres(3*(hi - lo)), rad(hi - lo);
    std::vector<int64_t> share(hi - lo);
    for (std::int64_t p = lo; p < hi; ++p)
    {
        for (int k = 0; k < 3; ++k) centres[3*(p - lo) + k] = table[p*nc + x + k];
        rad[p - lo] = radii[p*radiiStride];
        share[p - lo] = p;
    }
    int64_t nOwn = 0;
    double* ownCentres = nullptr;
    double* ownRadii = nullptr;
    int64_t* own = nullptr;
    if
    (
        vfe_mpi_route_particles
        (
            engine_, hi - lo, centres.data(), rad.data(), share.data(),
            &nOwn, &ownCentres, &ownRadii, &own
        ) != VFE_OK
    )
    {
        vfeFailed("vfe_mpi_route_particles");
    }
    rows.assign(own, own + nOwn);
    std::free(ownCentres);
    std::free(ownRadii);
    std::free(own);
    return rows;
}


void Foam::functionObjects::vfeVoidFraction::computeFrame(const long i)
{
    const label nCells = mesh_.nCells();
    std::vector<double> solid(nCells, 0.0);
    std::vector<double> eps(nCells, 1.0);
    std::vector<double> momentum(writeUs_ ? 3*nCells : 0, 0.0);
    double particleVolume = 0, deposited = 0;
    std::int64_t n = 0;

    if (i >= 0)
    {
        vfe::dumpFrame f;
        try
        {
            f = series_->read(i);
        }
        catch (const std::exception& err)
        {
            FatalErrorInFunction << err.what() << nl << exit(FatalError);
        }
        n = f.n;
        const int nc = int(f.columns.size());
        const int x = f.column("x");
        const int y = f.column("y");
        const int z = f.column("z");
        const int r = f.column("radius");
        const int d = f.column("diameter");
        const int id = f.column("id");
        if (x < 0 || y != x + 1 || z != x + 2 || (r < 0 && d < 0))
        {
            FatalErrorInFunction
                << series_->file(i) << ": the dump needs the columns x y z "
                << "(in this order) and radius or diameter; it has "
                << f.columns.size() << " columns" << nl << exit(FatalError);
        }
        const int vx = writeUs_ ? f.column("vx") : -1;
        if (writeUs_ && (vx < 0 || f.column("vy") != vx + 1 || f.column("vz") != vx + 2))
        {
            FatalErrorInFunction
                << series_->file(i) << ": writeUs needs the columns vx vy vz"
                << " (in this order) in the dump" << nl << exit(FatalError);
        }

        // A diameter column needs radii of its own; the radius column is read
        // in place (stride nc).
        std::vector<double> halfDiameters;
        if (r < 0)
        {
            halfDiameters.resize(n);
            for (std::int64_t p = 0; p < n; ++p) halfDiameters[p] = 0.5*f.table[p*nc + d];
        }
        const double* radii = r >= 0 ? f.table.data() + r : halfDiameters.data();
        const std::int64_t radiiStride = r >= 0 ? nc : 1;

        // This rank's particles: serial, every row, read in place from the
        // dump's table (row stride); in parallel, the rows whose centres lie
        // in its cells, packed. Ids are the dump's (the row number without an
        // id column, which is how the serial engine numbers them), so a
        // particle keeps its template rotation on any rank.
        const std::vector<std::int64_t> rows =
            ownRows(f.table, n, nc, x, radii, radiiStride);
        const std::int64_t nOwn = std::int64_t(rows.size());
        std::vector<int64_t> ids;
        if (id >= 0 || Pstream::parRun())
        {
            ids.resize(nOwn);
            for (std::int64_t k = 0; k < nOwn; ++k)
            {
                ids[k] = id >= 0 ? int64_t(f.table[rows[k]*nc + id]) : rows[k];
            }
        }
        std::vector<double> ownTable;
        vfe_particles particles = {};
        particles.n = nOwn;
        particles.ids = ids.empty() ? nullptr : ids.data();
        if (Pstream::parRun())
        {
            // Packed rows of x y z radius.
            ownTable.resize(4*nOwn);
            for (std::int64_t k = 0; k < nOwn; ++k)
            {
                for (int c = 0; c < 3; ++c) ownTable[4*k + c] = f.table[rows[k]*nc + x + c];
                ownTable[4*k + 3] = radii[rows[k]*radiiStride];
            }
            particles.centres = ownTable.data();
            particles.centres_stride = int64_t(4*sizeof(double));
            particles.radii = ownTable.data() + 3;
            particles.radii_stride = int64_t(4*sizeof(double));
        }
        else
        {
            particles.centres = f.table.data() + x;
            particles.centres_stride = int64_t(nc*sizeof(double));
            particles.radii = radii;
            particles.radii_stride = int64_t(radiiStride*sizeof(double));
        }
        if
        (
            vfe_compute_particles(engine_, &particles, solid.data())
         != VFE_OK
        )
        {
            vfeFailed("vfe_compute_particles");
        }
        if (vfe_void_fraction(engine_, eps.data()) != VFE_OK)
        {
            vfeFailed("vfe_void_fraction");
        }
        // Over all ranks in parallel.
        vfe_report rep;
        vfe_last_report(engine_, &rep);
        particleVolume = rep.particle_volume;
        deposited = rep.deposited_volume;

        if (writeUs_)
        {
            // Deposit velocity x particle volume: per cell, the particles'
            // momentum per density, which divided by the solid volume is the
            // volume-weighted particle velocity.
            std::vector<double> values(3*nOwn);
            for (std::int64_t k = 0; k < nOwn; ++k)
            {
                const double rad = radii[rows[k]*radiiStride];
                const double vol = 4.0/3.0*constant::mathematical::pi*rad*rad*rad;
                for (int c = 0; c < 3; ++c)
                {
                    values[3*k + c] = f.table[rows[k]*nc + vx + c]*vol;
                }
            }
            if
            (
                vfe_deposit(engine_, 3, values.data(), momentum.data())
             != VFE_OK
            )
            {
                vfeFailed("vfe_deposit");
            }
        }
    }

    scalarField& epsI = voidfraction_.primitiveFieldRef();
    forAll(epsI, c) epsI[c] = eps[c];
    voidfraction_.correctBoundaryConditions();
    if (writeUs_)
    {
        vectorField& UsI = Us_->primitiveFieldRef();
        forAll(UsI, c)
        {
            UsI[c] = solid[c] > 0
              ? vector(momentum[3*c], momentum[3*c+1], momentum[3*c+2])/solid[c]
              : vector::zero;
        }
        Us_->correctBoundaryConditions();
    }
    frame_ = i;

    Info<< type() << " " << name() << ": ";
    if (i >= 0)
    {
        Info<< "frame " << series_->file(i) << " (timestep "
            << series_->timestep(i) << ", " << n
            << " particles), deposited volume " << deposited
            << " of " << particleVolume << nl;
    }
    else
    {
        Info<< "no frame at or before t = " << time_.value()
            << ", voidfraction = 1" << nl;
    }
}


// * * * * * * * * * * * * * * * * Constructors  * * * * * * * * * * * * * * //

Foam::functionObjects::vfeVoidFraction::vfeVoidFraction
(
    const word& name,
    const Time& runTime,
    const dictionary& dict
)
:
    fvMeshFunctionObject(name, runTime, dict),
    demTimeStep_(0),
    writeUs_(false),
    engine_(nullptr),
    frame_(-1),
    voidfraction_
    (
        IOobject
        (
            dict.lookupOrDefault<word>("field", "voidfraction"),
            mesh_.time().timeName(),
            mesh_,
            IOobject::NO_READ,
            IOobject::NO_WRITE
        ),
        mesh_,
        dimensionedScalar("voidfraction", dimless, 1.0),
        zeroGradientFvPatchScalarField::typeName
    )
{
    createEngine();
    read(dict);
}


Foam::functionObjects::vfeVoidFraction::~vfeVoidFraction()
{
    vfe_destroy(engine_);
}


// * * * * * * * * * * * * * * * Member Functions  * * * * * * * * * * * * * //

bool Foam::functionObjects::vfeVoidFraction::read(const dictionary& dict)
{
    fvMeshFunctionObject::read(dict);

    dumps_ = dict.get<fileName>("dumps");
    dumps_.expand();
    if (!dumps_.isAbsolute())
    {
        dumps_ = time_.globalPath()/dumps_;
    }
    demTimeStep_ = dict.get<scalar>("demTimeStep");
    if (!(demTimeStep_ > 0))
    {
        FatalIOErrorInFunction(dict)
            << "demTimeStep must be > 0 (seconds per DEM timestep of the dumps)"
            << exit(FatalIOError);
    }
    options_ = dict.lookupOrDefault<string>("options", "");
    writeUs_ = dict.lookupOrDefault<Switch>("writeUs", false);

    try
    {
        series_.reset(new vfe::dumpSeries(dumps_));
    }
    catch (const std::exception& err)
    {
        FatalIOErrorInFunction(dict) << err.what() << exit(FatalIOError);
    }
    configureEngine();

    if (writeUs_ && !Us_)
    {
        Us_.reset
        (
            new volVectorField
            (
                IOobject
                (
                    "Us",
                    mesh_.time().timeName(),
                    mesh_,
                    IOobject::NO_READ,
                    IOobject::NO_WRITE
                ),
                mesh_,
                dimensionedVector("Us", dimVelocity, Zero),
                zeroGradientFvPatchVectorField::typeName
            )
        );
    }
    frame_ = -1;

    Info<< type() << " " << name() << ": " << series_->size()
        << " frames of " << dumps_ << ", options \"" << options_.c_str()
        << "\"" << nl;
    return true;
}


bool Foam::functionObjects::vfeVoidFraction::execute()
{
    if (mesh_.changing())
    {
        vfe_destroy(engine_);
        engine_ = nullptr;
        createEngine();
        configureEngine();
        frame_ = -1;
    }
    long i = series_->frameAt(time_.value(), demTimeStep_);
    if (i < 0) i = -2;
    if (i != frame_) computeFrame(i);
    return true;
}


bool Foam::functionObjects::vfeVoidFraction::write()
{
    voidfraction_.write();
    if (Us_) Us_->write();
    return true;
}


// ************************************************************************* //
