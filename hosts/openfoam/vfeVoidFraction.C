/*---------------------------------------------------------------------------*\
    vfe: void fraction of CFD cells from DEM particles
\*---------------------------------------------------------------------------*/

#include "vfeVoidFraction.H"
#include "dumpSeries.H"

#include "addToRunTimeSelectionTable.H"
#include "zeroGradientFvPatchFields.H"

#include <vfe/vfe.h>

#include <cmath>
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
    const pointField& pts = mesh_.points();
    const faceList& faces = mesh_.faces();
    const labelList& own = mesh_.faceOwner();
    const labelList& nei = mesh_.faceNeighbour();

    // vfe takes 64-bit indices; OpenFOAM's labels may be 32-bit, so this is
    // the one copy of the mesh (the engine keeps its own).
    std::vector<double> points(3*pts.size());
    forAll(pts, i)
    {
        for (direction d = 0; d < 3; ++d) points[3*i + d] = pts[i][d];
    }
    std::vector<int64_t> offsets(faces.size() + 1, 0);
    forAll(faces, f) offsets[f + 1] = offsets[f] + faces[f].size();
    std::vector<int64_t> facePoints(offsets.back());
    forAll(faces, f)
    {
        forAll(faces[f], k) facePoints[offsets[f] + k] = faces[f][k];
    }
    const std::vector<int64_t> owner(own.begin(), own.end());
    const std::vector<int64_t> neighbour(nei.begin(), nei.end());

    vfe_engine* e = nullptr;
    if
    (
        vfe_create_polymesh_arrays
        (
            pts.size(), points.data(), faces.size(), offsets.data(),
            facePoints.data(), owner.data(), mesh_.nInternalFaces(),
            neighbour.data(), &e
        ) != VFE_OK
    )
    {
        vfeFailed("vfe_create_polymesh_arrays");
    }
    engine_ = e;
}


void Foam::functionObjects::vfeVoidFraction::configureEngine()
{
    std::string opts = options_;
    if (writeUs_) opts += " weights=1";
    if (Pstream::parRun()) opts += " outside=drop";
    if (vfe_configure(engine_, opts.c_str()) != VFE_OK)
    {
        vfeFailed("vfe_configure");
    }
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

        // Centres and radii are read in place from the dump's table (row
        // stride); only a diameter column and the ids need arrays of their own.
        const int64_t rowBytes = int64_t(nc*sizeof(double));
        std::vector<double> radii;
        if (r < 0)
        {
            radii.resize(n);
            for (std::int64_t p = 0; p < n; ++p) radii[p] = 0.5*f.table[p*nc + d];
        }
        std::vector<int64_t> ids;
        if (id >= 0)
        {
            ids.resize(n);
            for (std::int64_t p = 0; p < n; ++p) ids[p] = int64_t(f.table[p*nc + id]);
        }
        vfe_particles particles = {};
        particles.n = n;
        particles.centres = f.table.data() + x;
        particles.centres_stride = rowBytes;
        particles.radii = r >= 0 ? f.table.data() + r : radii.data();
        particles.radii_stride = r >= 0 ? rowBytes : 0;
        particles.ids = id >= 0 ? ids.data() : nullptr;
        if
        (
            vfe_compute_particles(engine_, &particles, solid.data()) != VFE_OK
        )
        {
            vfeFailed("vfe_compute_particles");
        }
        if (vfe_void_fraction(engine_, eps.data()) != VFE_OK)
        {
            vfeFailed("vfe_void_fraction");
        }
        vfe_report rep;
        vfe_last_report(engine_, &rep);
        particleVolume = rep.particle_volume;
        deposited = rep.deposited_volume;

        if (writeUs_)
        {
            const int vx = f.column("vx");
            if (vx < 0 || f.column("vy") != vx + 1 || f.column("vz") != vx + 2)
            {
                FatalErrorInFunction
                    << series_->file(i) << ": writeUs needs the columns vx vy vz"
                    << " (in this order) in the dump" << nl << exit(FatalError);
            }
            // Deposit velocity x particle volume: per cell, the particles'
            // momentum per density, which divided by the solid volume is the
            // volume-weighted particle velocity.
            std::vector<double> values(3*n);
            for (std::int64_t p = 0; p < n; ++p)
            {
                const double rad = particles.radii
                    [p*(particles.radii_stride ? nc : 1)];
                const double vol = 4.0/3.0*constant::mathematical::pi*rad*rad*rad;
                for (int k = 0; k < 3; ++k)
                {
                    values[3*p + k] = f.table[p*nc + vx + k]*vol;
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
            << series_->timestep(i) << ", " << returnReduce(label(n), maxOp<label>())
            << " particles), deposited volume "
            << returnReduce(deposited, sumOp<scalar>())
            << " of " << returnReduce(particleVolume, maxOp<scalar>()) << nl;
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
